// SPDX-License-Identifier: Apache-2.0
// Finished tiles on a watch stream, as bytes: a WatchJobEvent that carries stored tiles, encoded
// around the coordinator's one encoded copy of each tile rather than through a parsed message.
// The coordinator keeps every tile it accepted as the bytes of its TileData (TileOutput::payload);
// a protobuf message that carried them would copy them twice more per watcher (into the message,
// then into gRPC's buffer). These events are instead a few bytes of framing (field tags and
// lengths) and slices that refer to the stored bytes, held alive by the slices until gRPC has
// sent them: the only copy left is the kernel's.
//
// The bytes are exactly what protobuf would encode for the same message (a client parses them
// with the generated WatchJobEvent); watch_wire_test.cpp checks that against protobuf itself.
#pragma once

#include <grpcpp/support/byte_buffer.h>

#include <cstddef>
#include <memory>
#include <string>

namespace tessera::server {

using SharedTile = std::shared_ptr<const std::string>;

// WatchJobEvent{tile: the one tile} (for clients that did not ask for batches).
grpc::ByteBuffer tile_event_bytes(const SharedTile& tile);
// WatchJobEvent{tiles: TileBatch{tiles: the n tiles, in order}}, n >= 1.
grpc::ByteBuffer tile_batch_event_bytes(const SharedTile* tiles, size_t n);

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "watch_wire.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/wire_format_lite.h>
#include <grpcpp/support/slice.h>

#include <vector>

#include "tessera/v1/client_service.pb.h"

namespace tessera::server {
namespace {

using google::protobuf::io::CodedOutputStream;
using google::protobuf::internal::WireFormatLite;

// The framing of one length-delimited field: its tag and its length, as protobuf encodes them
// (the library's own varint and tag encoders: the bytes are protobuf's, not a re-implementation).
std::string field_head(int field, size_t length) {
  uint8_t buf[16];  // a tag and a length: two varints of at most 5 bytes
  uint8_t* end = CodedOutputStream::WriteTagToArray(
      WireFormatLite::MakeTag(field, WireFormatLite::WIRETYPE_LENGTH_DELIMITED), buf);
  end = CodedOutputStream::WriteVarint32ToArray(uint32_t(length), end);
  return std::string(reinterpret_cast<const char*>(buf), size_t(end - buf));
}

// A slice of the stored tile's bytes, no copy: the slice holds a reference to the tile until gRPC
// has sent it (and the tile outlives an acknowledgement that frees the scheduler's own).
grpc::Slice tile_slice(const SharedTile& tile) {
  auto* keep = new SharedTile(tile);
  return grpc::Slice(const_cast<char*>(tile->data()), tile->size(),
                     [](void* p) { delete static_cast<SharedTile*>(p); }, keep);
}

// Slices for `head` (copied: a few bytes) then the tile.
void append_tile(std::vector<grpc::Slice>& out, const std::string& head, const SharedTile& tile) {
  out.emplace_back(head);
  if (!tile->empty()) out.push_back(tile_slice(tile));
}

}  // namespace

grpc::ByteBuffer tile_event_bytes(const SharedTile& tile) {
  std::vector<grpc::Slice> slices;
  append_tile(slices, field_head(v1::WatchJobEvent::kTileFieldNumber, tile->size()), tile);
  return grpc::ByteBuffer(slices.data(), slices.size());
}

grpc::ByteBuffer tile_batch_event_bytes(const SharedTile* tiles, size_t n) {
  // The batch's length is the sum of its elements' framing and bytes, known before any is sent.
  std::vector<std::string> heads(n);
  size_t batch = 0;
  for (size_t i = 0; i < n; ++i) {
    heads[i] = field_head(v1::TileBatch::kTilesFieldNumber, tiles[i]->size());
    batch += heads[i].size() + tiles[i]->size();
  }
  std::vector<grpc::Slice> slices;
  slices.reserve(2 * n + 1);
  slices.emplace_back(field_head(v1::WatchJobEvent::kTilesFieldNumber, batch));
  for (size_t i = 0; i < n; ++i) append_tile(slices, heads[i], tiles[i]);
  return grpc::ByteBuffer(slices.data(), slices.size());
}

}  // namespace tessera::server

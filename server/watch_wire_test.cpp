// SPDX-License-Identifier: Apache-2.0
// Watch events built around stored tiles (watch_wire.h) against protobuf itself: the bytes are the
// ones protobuf encodes for the same message, they parse back to the same tiles, the tiles' bytes
// are referred to rather than copied, and they stay valid after the coordinator has dropped its
// copy. Then the outbox of a raw stream: messages serialized when written, in order with tiles.
#include "watch_wire.h"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "stream_outbox.h"
#include "tessera/v1/client_service.pb.h"

namespace tessera::server {
namespace {

namespace v1 = tessera::v1;

std::string bytes_of(const grpc::ByteBuffer& b) {
  std::vector<grpc::Slice> slices;
  EXPECT_TRUE(b.Dump(&slices).ok());
  std::string out;
  for (const grpc::Slice& s : slices) out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return out;
}

// Does one of the buffer's slices start at the tile's own bytes (no copy)?
bool refers_to(const grpc::ByteBuffer& b, const SharedTile& tile) {
  std::vector<grpc::Slice> slices;
  EXPECT_TRUE(b.Dump(&slices).ok());
  for (const grpc::Slice& s : slices) {
    if (reinterpret_cast<const char*>(s.begin()) == tile->data() && s.size() == tile->size()) return true;
  }
  return false;
}

// A tile as the coordinator stores it: its TileData, encoded. `pixels` bytes of rgb, so the
// lengths cross the varint boundaries (1, 2 and 3 bytes) as the tile sizes vary.
SharedTile stored_tile(std::mt19937& rng, int index, size_t pixels) {
  v1::TileData t;
  t.set_job_id("job-" + std::to_string(index));
  t.set_frame(index % 7);
  t.set_tile_index(index);
  std::string rgb(pixels, '\0');
  for (char& c : rgb) c = char(rng());
  t.set_rgb(rgb);
  t.set_seconds(0.001 * index);
  return std::make_shared<const std::string>(t.SerializeAsString());
}

TEST(WatchWire, BatchEventsAreProtobufsOwnBytesAroundTheStoredTiles) {
  std::mt19937 rng(7);
  for (size_t n : {size_t(1), size_t(2), size_t(5), size_t(64)}) {
    std::vector<SharedTile> tiles;
    for (size_t i = 0; i < n; ++i) {
      const size_t sizes[] = {0, 90, 127, 128, 16000, 16383, 16384, 70000};
      tiles.push_back(stored_tile(rng, int(i), sizes[(i + n) % 8]));
    }
    v1::WatchJobEvent expected;
    for (const SharedTile& t : tiles) expected.mutable_tiles()->add_tiles(*t);
    grpc::ByteBuffer built = tile_batch_event_bytes(tiles.data(), tiles.size());
    EXPECT_EQ(bytes_of(built), expected.SerializeAsString()) << n << " tiles";
    for (const SharedTile& t : tiles) EXPECT_TRUE(refers_to(built, t)) << "a tile of " << t->size() << " bytes was copied";

    // The coordinator may drop its tiles (a frame acknowledged) while the event waits to be sent.
    const std::string before = bytes_of(built);
    tiles.clear();
    v1::WatchJobEvent parsed;
    ASSERT_TRUE(parsed.ParseFromString(bytes_of(built)));
    EXPECT_EQ(parsed.SerializeAsString(), before);
    ASSERT_EQ(size_t(parsed.tiles().tiles_size()), n);
    v1::TileData last;
    ASSERT_TRUE(last.ParseFromString(parsed.tiles().tiles(int(n) - 1)));
    EXPECT_EQ(last.tile_index(), int(n) - 1);
  }
}

TEST(WatchWire, ASingleTileEventIsTheTileAsItsOwnMessage) {
  std::mt19937 rng(11);
  for (size_t pixels : {size_t(0), size_t(100), size_t(12288)}) {
    SharedTile tile = stored_tile(rng, 3, pixels);
    v1::WatchJobEvent expected;
    ASSERT_TRUE(expected.mutable_tile()->ParseFromString(*tile));
    grpc::ByteBuffer built = tile_event_bytes(tile);
    EXPECT_EQ(bytes_of(built), expected.SerializeAsString());
    EXPECT_TRUE(refers_to(built, tile));
  }
}

struct RawReactor {
  std::vector<std::string> written;
  bool finished = false;
  void StartWrite(const grpc::ByteBuffer* b) { written.push_back(bytes_of(*b)); }
  void Finish(const grpc::Status&) { finished = true; }
};

TEST(WatchWire, ARawStreamsOutboxSerializesMessagesInOrderWithTheTiles) {
  std::mt19937 rng(3);
  RawReactor r;
  Outbox<RawReactor, v1::WatchJobEvent, grpc::ByteBuffer> box(&r);
  box.set_batching([](grpc::ByteBuffer* out, const SharedTile* t, size_t n) { *out = tile_batch_event_bytes(t, n); },
                   8, size_t(1) << 20);
  v1::WatchJobEvent status;
  status.mutable_status()->set_job_id("j");
  box.push(status);
  const SharedTile a = stored_tile(rng, 0, 300), b = stored_tile(rng, 1, 300);
  box.push_shared(a);
  box.push_shared(b);
  box.push_deferred([](v1::WatchJobEvent* e) { e->set_frame_done(4); });
  box.finish(grpc::Status::OK);
  box.pump();
  for (int i = 0; i < 10 && !r.finished; ++i) box.on_write_done(true);
  ASSERT_TRUE(r.finished);
  ASSERT_EQ(r.written.size(), 3u);
  EXPECT_EQ(r.written[0], status.SerializeAsString());
  v1::WatchJobEvent tiles;
  ASSERT_TRUE(tiles.ParseFromString(r.written[1]));
  ASSERT_EQ(tiles.tiles().tiles_size(), 2);
  EXPECT_EQ(tiles.tiles().tiles(0), *a);
  EXPECT_EQ(tiles.tiles().tiles(1), *b);
  v1::WatchJobEvent done;
  ASSERT_TRUE(done.ParseFromString(r.written[2]));
  EXPECT_EQ(done.frame_done(), 4);
}

}  // namespace
}  // namespace tessera::server

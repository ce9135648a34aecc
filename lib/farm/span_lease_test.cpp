// SPDX-License-Identifier: Apache-2.0
#include "span_lease.h"

#include <gtest/gtest.h>

#include <limits>

#include "farm/tile_codec.h"
#include "tile/tile_grid.h"

namespace tessera::farm {
namespace {

namespace v1 = tessera::v1;

// A span of `count` tiles from `first` in a 100x50 frame cut in tiles of 32 (4 x 2 tiles, the
// last column 4 pixels wide, the last row 18 high).
v1::Assignment span_of(int first, int count) {
  v1::Assignment a;
  a.set_lease_id(42);
  a.set_job_id("0123456789ab");
  a.set_bundle_sha256("ab12");
  a.mutable_overrides()->set_spp(7);
  a.set_frame(3);
  a.set_tile_index(first);
  a.set_tile_count(count);
  a.set_tile_size(32);
  a.set_frame_width(100);
  a.set_frame_height(50);
  farm::to_proto(TileGrid(100, 50, 32).rect(first), a.mutable_rect());
  return a;
}

TEST(SpanLease, ASingleTileLeaseComesBackAsItCame) {
  for (int count : {0, 1}) {
    v1::Assignment a;
    a.set_lease_id(9);
    a.set_tile_index(5);
    a.set_tile_count(count);
    a.mutable_rect()->set_width(16);
    a.set_sample_plan("plan");  // a single tile's plan is kept
    std::vector<v1::Assignment> tiles;
    EXPECT_EQ(split_span(a, &tiles), "");
    ASSERT_EQ(tiles.size(), 1u);
    EXPECT_EQ(tiles[0].SerializeAsString(), a.SerializeAsString());
  }
}

TEST(SpanLease, ASpanIsCutIntoItsTilesFromTheGrid) {
  const v1::Assignment a = span_of(2, 4);  // tiles 2, 3 (the narrow one), then 4, 5 of the next row
  std::vector<v1::Assignment> tiles;
  ASSERT_EQ(split_span(a, &tiles), "");
  ASSERT_EQ(tiles.size(), 4u);
  const TileGrid grid(100, 50, 32);
  for (int i = 0; i < 4; ++i) {
    const v1::Assignment& t = tiles[size_t(i)];
    EXPECT_EQ(t.lease_id(), 42u);
    EXPECT_EQ(t.tile_index(), 2 + i);
    EXPECT_EQ(t.tile_count(), 0);  // each one a single-tile assignment
    EXPECT_EQ(farm::from_proto(t.rect()), grid.rect(2 + i));
    EXPECT_EQ(t.job_id(), a.job_id());
    EXPECT_EQ(t.bundle_sha256(), a.bundle_sha256());
    EXPECT_EQ(t.frame(), 3);
    EXPECT_EQ(t.overrides().spp(), 7);
  }
  EXPECT_EQ(farm::from_proto(tiles[1].rect()), (TileRect{96, 0, 4, 32}));
  EXPECT_EQ(farm::from_proto(tiles[3].rect()), (TileRect{32, 32, 32, 18}));
}

TEST(SpanLease, TheWholeFrameIsASpan) {
  std::vector<v1::Assignment> tiles;
  ASSERT_EQ(split_span(span_of(0, 8), &tiles), "");
  EXPECT_EQ(tiles.size(), 8u);
  EXPECT_EQ(tiles.back().tile_index(), 7);
}

TEST(SpanLease, MalformedSpansAreRefused) {
  const auto refused = [](const v1::Assignment& a) {
    std::vector<v1::Assignment> tiles(3);
    const std::string problem = split_span(a, &tiles);
    if (!problem.empty()) {
      EXPECT_TRUE(tiles.empty()) << problem;  // nothing half cut is left to render
    }
    return !problem.empty();
  };
  EXPECT_FALSE(refused(span_of(0, 2)));
  EXPECT_TRUE(refused(span_of(7, 2)));  // runs off the grid's last tile
  EXPECT_TRUE(refused(span_of(0, 9)));  // more tiles than the frame has
  v1::Assignment a = span_of(0, 2);
  a.set_tile_count(-3);
  EXPECT_TRUE(refused(a));
  a.set_tile_count(kMaxSpanTiles + 1);
  EXPECT_TRUE(refused(a));
  for (auto grid :
       {&v1::Assignment::set_tile_size, &v1::Assignment::set_frame_width, &v1::Assignment::set_frame_height}) {
    for (int bad : {0, -32}) {
      a = span_of(0, 2);
      (a.*grid)(bad);
      EXPECT_TRUE(refused(a));
    }
  }
  a = span_of(0, 2);
  a.set_tile_index(-1);
  EXPECT_TRUE(refused(a));
  a = span_of(1, 2);
  a.mutable_rect()->set_x0(0);  // tile 0's rect for a span from tile 1
  EXPECT_TRUE(refused(a));
  a = span_of(0, 2);
  a.set_sample_plan("plan");
  EXPECT_TRUE(refused(a));
}

TEST(SpanLease, HugeGridsNeitherOverflowNorPass) {
  constexpr int kMax = std::numeric_limits<int>::max();
  std::vector<v1::Assignment> tiles;
  v1::Assignment a = span_of(0, 2);
  a.set_frame_width(kMax);  // TileGrid's column count would overflow
  EXPECT_NE(split_span(a, &tiles), "");
  // A grid of more tiles than an int counts: the span's indices must still be ints.
  a.set_tile_size(1);
  a.set_frame_width(1 << 20);
  a.set_frame_height(1 << 20);
  a.set_tile_index(kMax);
  a.mutable_rect()->set_x0(kMax % (1 << 20));
  a.mutable_rect()->set_y0(kMax / (1 << 20));
  a.mutable_rect()->set_width(1);
  a.mutable_rect()->set_height(1);
  EXPECT_NE(split_span(a, &tiles), "");  // the second tile, kMax + 1, is no int index
  a.set_tile_index(kMax - 1);
  a.mutable_rect()->set_x0((kMax - 1) % (1 << 20));
  ASSERT_EQ(split_span(a, &tiles), "");
  ASSERT_EQ(tiles.size(), 2u);
  EXPECT_EQ(tiles[1].tile_index(), kMax);
  EXPECT_EQ(farm::from_proto(tiles[1].rect()), (TileRect{kMax % (1 << 20), kMax / (1 << 20), 1, 1}));
}

}  // namespace
}  // namespace tessera::farm

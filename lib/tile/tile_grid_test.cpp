// SPDX-License-Identifier: Apache-2.0
#include "tile/tile_grid.h"

#include <gtest/gtest.h>

#include <vector>

namespace tessera {
namespace {

TEST(TileGridTest, CountsRoundUpAndEdgeTilesAreCutShort) {
  const TileGrid g(100, 50, 32);
  EXPECT_EQ(g.columns(), 4);  // 32 + 32 + 32 + 4
  EXPECT_EQ(g.rows(), 2);     // 32 + 18
  EXPECT_EQ(g.count(), 8);
  EXPECT_EQ(g.rect(0), (TileRect{0, 0, 32, 32}));
  EXPECT_EQ(g.rect(3), (TileRect{96, 0, 4, 32}));
  EXPECT_EQ(g.rect(4), (TileRect{0, 32, 32, 18}));
  EXPECT_EQ(g.rect(7), (TileRect{96, 32, 4, 18}));
}

TEST(TileGridTest, TilesCoverEveryPixelExactlyOnceInRowMajorOrder) {
  for (int size : {1, 7, 16, 33, 256}) {
    const TileGrid g(61, 37, size);
    std::vector<int> hits(61 * 37, 0);
    const std::vector<TileRect> rects = g.rects();
    ASSERT_EQ(int(rects.size()), g.count());
    for (int i = 0; i < g.count(); ++i) {
      const TileRect r = rects[size_t(i)];
      EXPECT_EQ(r, g.rect(i));
      if (i > 0) {  // row-major: left to right, then the next row down
        const TileRect p = rects[size_t(i - 1)];
        EXPECT_TRUE(r.y0 > p.y0 || (r.y0 == p.y0 && r.x0 > p.x0)) << "size " << size << " tile " << i;
      }
      for (int y = r.y0; y < r.y0 + r.height; ++y) {
        for (int x = r.x0; x < r.x0 + r.width; ++x) ++hits[size_t(y * 61 + x)];
      }
    }
    for (int h : hits) ASSERT_EQ(h, 1) << "size " << size;
  }
}

TEST(TileGridTest, ContainsOnlyItsIndicesAndANonPositiveSizeIsOne) {
  const TileGrid g(3, 2, 0);
  EXPECT_EQ(g.size(), 1);
  EXPECT_EQ(g.count(), 6);
  EXPECT_TRUE(g.contains(5));
  EXPECT_FALSE(g.contains(6));
  EXPECT_FALSE(g.contains(-1));
  EXPECT_EQ(TileGrid(0, 10, 8).count(), 0);
}

}  // namespace
}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "tile/frame_assembly.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

namespace tessera {
namespace {

// A tile whose every value encodes the pixel it belongs to, so a misplaced row shows.
TileResult coded_tile(const TileRect& r, bool with_spp = true) {
  TileResult t;
  t.rect = r;
  for (int y = r.y0; y < r.y0 + r.height; ++y) {
    for (int x = r.x0; x < r.x0 + r.width; ++x) {
      const float code = float(y * 1000 + x);
      t.rgb.insert(t.rgb.end(), {code, code + 0.25f, code + 0.5f});
      t.variance.push_back(code + 0.75f);
      if (with_spp) t.spp.push_back(uint32_t(y * 1000 + x));
    }
  }
  return t;
}

TEST(FrameAssemblyTest, TilesInAnyOrderMakeTheSameFrameWithEveryPixelWhereItBelongs) {
  const TileGrid grid(45, 29, 8);
  std::vector<int> order(size_t(grid.count()));
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  FrameAssembly a(grid);
  for (int i : order) {
    bool placed = false;
    ASSERT_EQ(a.place(i, coded_tile(grid.rect(i)), &placed), "");
    EXPECT_TRUE(placed);
    EXPECT_EQ(a.complete(), a.tiles_done() == grid.count());
  }
  ASSERT_TRUE(a.complete());
  for (int y = 0; y < 29; ++y) {
    for (int x = 0; x < 45; ++x) {
      const float code = float(y * 1000 + x);
      EXPECT_EQ(a.image().at(x, y)[0], code);
      EXPECT_EQ(a.image().at(x, y)[2], code + 0.5f);
      EXPECT_EQ(a.variance()[size_t(y * 45 + x)], code + 0.75f);
      EXPECT_EQ(a.spp()[size_t(y * 45 + x)], uint32_t(y * 1000 + x));
    }
  }
}

TEST(FrameAssemblyTest, TheFirstCopyOfATileWins) {
  const TileGrid grid(16, 16, 8);
  FrameAssembly a(grid);
  ASSERT_EQ(a.place(1, coded_tile(grid.rect(1))), "");
  TileResult second = coded_tile(grid.rect(1));
  std::fill(second.rgb.begin(), second.rgb.end(), -1.0f);
  bool placed = true;
  EXPECT_EQ(a.place(1, second, &placed), "");
  EXPECT_FALSE(placed);
  EXPECT_EQ(a.tiles_done(), 1);
  EXPECT_EQ(a.image().at(8, 0)[0], 8.0f);
}

TEST(FrameAssemblyTest, RefusesATileThatIsNotTheOneItClaimsToBe) {
  const TileGrid grid(20, 10, 8);
  FrameAssembly a(grid);
  EXPECT_NE(a.place(grid.count(), coded_tile(grid.rect(0))), "");
  EXPECT_NE(a.place(-1, coded_tile(grid.rect(0))), "");
  EXPECT_NE(a.place(1, coded_tile(grid.rect(0))), "");  // tile 0's rectangle sent as tile 1
  TileResult short_rows = coded_tile(grid.rect(2));
  short_rows.rgb.pop_back();
  EXPECT_NE(a.place(2, short_rows), "");
  TileResult short_variance = coded_tile(grid.rect(2));
  short_variance.variance.pop_back();
  EXPECT_NE(a.place(2, short_variance), "");
  EXPECT_EQ(a.tiles_done(), 0);
  EXPECT_FALSE(a.has(2));
}

TEST(FrameAssemblyTest, ColourOnlyKeepsNoLayersAndTilesWithoutSppKeepTheLayer) {
  const TileGrid grid(8, 8, 4);
  FrameAssembly colour(grid, FrameAssembly::Layers::kColour);
  TileResult t = coded_tile(grid.rect(3));
  t.variance.clear();
  ASSERT_EQ(colour.place(3, t), "");
  EXPECT_TRUE(colour.variance().empty());
  EXPECT_TRUE(colour.spp().empty());
  EXPECT_EQ(colour.image().at(7, 7)[1], 7007.25f);

  FrameAssembly full(grid);
  ASSERT_EQ(full.place(0, coded_tile(grid.rect(0), /*with_spp=*/false)), "");
  EXPECT_EQ(full.spp()[0], 0u);
  EXPECT_EQ(full.variance()[9], 1001.75f);
}

}  // namespace
}  // namespace tessera

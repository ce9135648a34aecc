// SPDX-License-Identifier: Apache-2.0
// The pieces of a frame target's passes that a farm's coordinator and workers must agree on.
#include "sampling/pass_plan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <utility>

namespace tessera {
namespace {

TEST(PassPlan, ATileMeetsTheBlocksItTouchesAndReportsThoseThatStartInIt) {
  constexpr int B = kAllocationBlock;
  const BlockGrid g(75, 53);  // the last column and row of blocks clipped (75 and 53 are odd)
  EXPECT_EQ(g.cols, 75 / B + 1);
  EXPECT_EQ(g.rows, 53 / B + 1);
  // Counted pixel by pixel: the blocks a rectangle holds a pixel of, and those whose first pixel
  // (both coordinates multiples of B) it holds.
  auto brute = [&](const TileRect& t) {
    std::set<std::pair<int, int>> met;
    int origins = 0;
    for (int y = t.y0; y < t.y0 + t.height; ++y) {
      for (int x = t.x0; x < t.x0 + t.width; ++x) {
        met.insert({x / B, y / B});
        origins += x % B == 0 && y % B == 0;
      }
    }
    return std::pair{met, origins};
  };
  for (const TileRect t : {TileRect{7, 2, 12, 12}, TileRect{0, 0, 4, 4}, TileRect{1, 1, 1, 1}, TileRect{70, 50, 5, 3}}) {
    const auto [met, origins] = brute(t);
    const BlockGrid::Range r = g.meeting(t);
    EXPECT_EQ(r.count(), int(met.size())) << t.x0 << "," << t.y0;
    EXPECT_EQ(met.begin()->first, r.col0);
    EXPECT_EQ(met.begin()->second, r.row0);
    EXPECT_EQ(met.rbegin()->first, r.col1 - 1);
    EXPECT_EQ(met.rbegin()->second, r.row1 - 1);
    EXPECT_EQ(g.origins_in(t), origins) << t.x0 << "," << t.y0;
  }
  EXPECT_EQ(g.origins_in({1, 1, 1, 1}), 0);  // inside one block, not at its start
  // Every block is reported by exactly one tile of any tiling.
  for (int tile : {5, 7, 12, 32}) {
    int total = 0;
    for (int y = 0; y < 53; y += tile) {
      for (int x = 0; x < 75; x += tile) total += g.origins_in({x, y, std::min(tile, 75 - x), std::min(tile, 53 - y)});
    }
    EXPECT_EQ(total, g.count()) << tile;
  }
}

TEST(PassPlan, PlansSurviveTheWireAndBadBytesAreRefused) {
  const SamplePlan plan = {8, 16, 1024, 65536, 0xfffffff8u};
  SamplePlan back;
  ASSERT_EQ(decode_plan(encode_plan(plan), &back), "");
  EXPECT_EQ(back, plan);
  EXPECT_EQ(encode_plan({1})[0], '\x01');  // little-endian, whatever the host
  EXPECT_EQ(decode_plan(std::string(7, 'x'), &back), "sample plan of 7 bytes is not a whole number of 4-byte counts");
  ASSERT_EQ(decode_plan("", &back), "");
  EXPECT_TRUE(back.empty());  // the pilot
}

TEST(PassPlan, ABlockRecordMeasuresItsRateOnlyWhenItsCountMoves) {
  BlockStat before;
  before.spp = 8;
  before.mse = before.shape_mse = 8e-4;
  before.rate = first_rate(SamplerKind::kSobol);
  BlockStat now = before;
  now.spp = 32;
  now.mse = now.shape_mse = 8e-4 / 16;  // four times the samples, a sixteenth of the error: rate 2
  EXPECT_DOUBLE_EQ(updated_stat(before, now).rate, 2.0);
  now.shape_mse = 8e-4 / 1024;  // faster than any sampler falls: clamped
  EXPECT_DOUBLE_EQ(updated_stat(before, now).rate, 2.5);
  BlockStat same = before;
  same.mse = 1;  // rendered again at the same count (another block of its tile moved): kept
  EXPECT_EQ(updated_stat(before, same).mse, before.mse);
  EXPECT_DOUBLE_EQ(first_rate(SamplerKind::kIndependent), 1.0);
}

// A frame of 2 x 2 allocation blocks (or `cols` x 1), each with `spp` samples, its own error
// and shape `mse`, cost 1 and mean value 0.5 grey.
std::vector<BlockStat> blocks_of(int count, double mse, uint32_t spp = 8) {
  std::vector<BlockStat> stats(static_cast<size_t>(count));
  for (int b = 0; b < count; ++b) {
    BlockStat& s = stats[size_t(b)];
    s.block = b;
    s.spp = spp;
    s.pixels = uint32_t(kAllocationBlock * kAllocationBlock);
    s.cost = 1;
    s.mse = s.shape_mse = mse;
    s.rate = first_rate(SamplerKind::kSobol);
    s.mean = {0.5f, 0.5f, 0.5f};
  }
  return stats;
}

TEST(PassPlan, AFrameThatMeetsItsTargetTakesNoMorePasses) {
  constexpr int B = kAllocationBlock;
  ImageSettings img;
  img.width = img.height = 2 * B;
  img.target_rmse = 0.011;
  const BlockGrid g(img.width, img.height);
  ASSERT_EQ(g.count(), 4);
  std::vector<BlockStat> stats = blocks_of(4, 1e-5);
  stats[3].mse = stats[3].shape_mse = 4e-4;
  EXPECT_FALSE(next_pass_counts(stats, g, img, 1).has_value()) << "mean MSE 1.075e-4 <= 1.21e-4: done";
  img.target_rmse = 0.005;
  const auto next = next_pass_counts(stats, g, img, 1);
  ASSERT_TRUE(next.has_value());
  EXPECT_GT((*next)[3], (*next)[0]) << "the noisy block takes the most";
  EXPECT_FALSE(next_pass_counts(stats, g, img, kMaxTargetPasses).has_value()) << "passes are bounded";
  EXPECT_EQ(tile_plan(g, {B, 0, B, 2 * B}, *next), (SamplePlan{(*next)[1], (*next)[3]}));
}

TEST(PassPlan, AnEdgeItsSamplesMissedIsFoundAcrossTheBlockBoundary) {
  // A row of eight blocks, every one reading the same small error (their samples agree), the
  // left four sky-blue and the right four black: an edge between blocks 3 and 4 that neither
  // block's own samples show (the Whitted horizon at a pilot of 2). The two blocks beside it take
  // more samples than any other; blocks away from it, the same as with no edge at all.
  constexpr int B = kAllocationBlock;
  ImageSettings img;
  img.width = 8 * B;
  img.height = B;
  img.target_rmse = 0.002;
  img.min_spp = 2;
  const BlockGrid g(img.width, img.height);
  std::vector<BlockStat> stats = blocks_of(8, 1e-5, 2);
  const std::vector<BlockStat> flat = stats;
  for (int b = 0; b < 4; ++b) stats[size_t(b)].mean = {0.25f, 0.45f, 0.8f};
  for (int b = 4; b < 8; ++b) stats[size_t(b)].mean = {0.0f, 0.0f, 0.0f};
  const auto next = next_pass_counts(stats, g, img, 1);
  const auto next_flat = next_pass_counts(flat, g, img, 1);
  ASSERT_TRUE(next.has_value() && next_flat.has_value());
  for (int b : {0, 1, 2, 5, 6, 7}) {
    EXPECT_GT((*next)[3], (*next)[size_t(b)]) << b;
    EXPECT_GT((*next)[4], (*next)[size_t(b)]) << b;
  }
  EXPECT_EQ((*next)[0], (*next)[7]);
  EXPECT_EQ((*next)[3], (*next)[4]) << "the edge is symmetric";
  // The floor moves samples; it does not raise the frame's own level: a frame whose blocks' own
  // error meets the target takes no more passes, edge or no edge.
  img.target_rmse = 0.004;
  EXPECT_FALSE(next_pass_counts(stats, g, img, 1).has_value());
}

// A frame whose first row of blocks is frozen (the lattice sampler's smooth pixels): those blocks
// keep their counts, and the others take the samples that bring the frame's predicted MSE to the
// target with the frozen error counted as it is; when the frozen error alone exceeds the target,
// the others are held to half the target, not pushed toward max_spp.
TEST(PassPlan, FrozenBlocksKeepTheirCountsAndTheOthersShareWhatIsLeftOfTheTarget) {
  const BlockGrid g(8, 4);  // 4 x 2 blocks of 2 x 2 pixels
  ImageSettings img;
  img.target_rmse = 0.1;  // frame MSE 0.01
  img.max_spp = 1024;
  auto plan = [&](double frozen_mse) {
    std::vector<BlockStat> stats(size_t(g.count()));
    FrozenPixels frozen;
    frozen.blocks.assign(size_t(g.count()), 0);
    frozen.frame_pixels = 32;
    for (int b = 0; b < g.count(); ++b) {
      BlockStat& s = stats[size_t(b)];
      s.block = b;
      s.pixels = 4;
      s.rate = 1.5;
      s.cost = 3;
      const bool is_frozen = b < g.cols;
      s.spp = is_frozen ? 1 : 2;
      s.mse = s.shape_mse = is_frozen ? frozen_mse : 0.08;
      frozen.blocks[size_t(b)] = uint8_t(is_frozen);
      if (is_frozen) frozen.error += 4 * frozen_mse;
    }
    const auto want = next_pass_counts(stats, g, img, 1, frozen);
    EXPECT_TRUE(want.has_value());
    for (int b = 0; b < g.cols; ++b) EXPECT_EQ((*want)[size_t(b)], 1u) << b;
    // Every open block alike: one count, the least (in pairs) whose MSE 0.08 (2 / n)^1.5 meets
    // what is left.
    const uint32_t n = (*want)[size_t(g.cols)];
    for (int b = g.cols; b < g.count(); ++b) EXPECT_EQ((*want)[size_t(b)], n) << b;
    return n;
  };
  auto mse_at = [](uint32_t n) { return 0.08 * std::pow(2.0 / double(n), 1.5); };
  // Frozen error 16 x 0.005 = 0.08 of the frame's 32 x 0.01: the open 16 pixels have 0.015 each.
  const uint32_t n = plan(0.005);
  EXPECT_LE(mse_at(n), 0.015 * 1.0001);
  EXPECT_GT(mse_at(n - 2), 0.015);
  // Frozen error 16 x 0.05 = 0.8, over the whole target: the open pixels are held to 0.005.
  const uint32_t m = plan(0.05);
  EXPECT_LE(mse_at(m), 0.005 * 1.0001);
  EXPECT_GT(mse_at(m - 2), 0.005);
}

}  // namespace
}  // namespace tessera

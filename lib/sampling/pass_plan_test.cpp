// The pieces of a frame target's passes that a farm's coordinator and workers must agree on.
#include "sampling/pass_plan.h"

#include <gtest/gtest.h>

namespace tessera {
namespace {

TEST(PassPlan, ATileMeetsTheBlocksItTouchesAndReportsThoseThatStartInIt) {
  const BlockGrid g(75, 53);  // 19 x 14 blocks, the last column and row clipped
  EXPECT_EQ(g.cols, 19);
  EXPECT_EQ(g.rows, 14);
  const BlockGrid::Range r = g.meeting({7, 2, 12, 12});  // pixels 7..18 x 2..13
  EXPECT_EQ(r.col0, 1);
  EXPECT_EQ(r.col1, 5);
  EXPECT_EQ(r.row0, 0);
  EXPECT_EQ(r.row1, 4);
  EXPECT_EQ(g.origins_in({7, 2, 12, 12}), 3 * 3);  // blocks starting at x 8, 12, 16 and y 4, 8, 12
  EXPECT_EQ(g.origins_in({0, 0, 4, 4}), 1);
  EXPECT_EQ(g.origins_in({1, 1, 2, 2}), 0);  // inside one block, not at its start
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
  ASSERT_TRUE(decode_plan(encode_plan(plan), &back));
  EXPECT_EQ(back, plan);
  EXPECT_EQ(encode_plan({1})[0], '\x01');  // little-endian, whatever the host
  EXPECT_FALSE(decode_plan(std::string(7, 'x'), &back));
  ASSERT_TRUE(decode_plan("", &back));
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

TEST(PassPlan, AFrameThatMeetsItsTargetTakesNoMorePasses) {
  ImageSettings img;
  img.width = img.height = 8;
  img.target_rmse = 0.011;
  const BlockGrid g(8, 8);
  std::vector<BlockStat> stats(4);
  for (int b = 0; b < 4; ++b) {
    stats[size_t(b)].block = b;
    stats[size_t(b)].spp = 8;
    stats[size_t(b)].pixels = 16;
    stats[size_t(b)].cost = 1;
    stats[size_t(b)].mse = stats[size_t(b)].shape_mse = b == 3 ? 4e-4 : 1e-5;
  }
  EXPECT_FALSE(next_pass_counts(stats, g, img, 1).has_value()) << "mean MSE 1.075e-4 <= 1.21e-4: done";
  img.target_rmse = 0.005;
  const auto next = next_pass_counts(stats, g, img, 1);
  ASSERT_TRUE(next.has_value());
  EXPECT_GT((*next)[3], (*next)[0]) << "the noisy block takes the most";
  EXPECT_FALSE(next_pass_counts(stats, g, img, kMaxTargetPasses).has_value()) << "passes are bounded";
  EXPECT_EQ(tile_plan(g, {4, 0, 4, 8}, *next), (SamplePlan{(*next)[1], (*next)[3]}));
}

}  // namespace
}  // namespace tessera

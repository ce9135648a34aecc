// SPDX-License-Identifier: Apache-2.0
// The allocation against its closed form: with every block at the same rate a and no bound
// reached, block b's count is proportional to (m_b n_b^a / c_b)^(1 / (a + 1)).
#include "sampling/sample_allocation.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tessera {
namespace {

BlockStat block(double mse, double cost, double rate = 1, uint32_t spp = 8, uint32_t pixels = 16) {
  BlockStat s;
  s.spp = spp;
  s.pixels = pixels;
  s.mse = s.shape_mse = mse;
  s.cost = cost;
  s.rate = rate;
  return s;
}

TEST(SampleAllocation, SamplesGoAsDeviationOverTheRootOfCost) {
  // Four times the variance: twice the samples; four times the cost: half of them (a = 1).
  const std::vector<BlockStat> blocks = {block(1e-3, 1), block(4e-3, 1), block(4e-3, 4)};
  const std::vector<uint32_t> n = allocate_samples(blocks, {1e-5, 8, 1 << 16});
  ASSERT_EQ(n.size(), 3u);
  EXPECT_NEAR(double(n[1]) / double(n[0]), 2.0, 0.05);
  EXPECT_NEAR(double(n[2]) / double(n[0]), 1.0, 0.05);
  // The target is met, and not by much more than the rounding to whole packets gives away.
  const double mse = predicted_frame_mse(blocks, n);
  EXPECT_LE(mse, 1e-5);
  EXPECT_GT(mse, 0.95e-5);
}

TEST(SampleAllocation, TheRateOfConvergenceShiftsTheShares) {
  // At a = 2 the closed form is (m / c)^(1/3) times the common factor: 8x the variance, 2x the samples.
  const std::vector<BlockStat> blocks = {block(1e-3, 1, 2), block(8e-3, 1, 2)};
  const std::vector<uint32_t> n = allocate_samples(blocks, {1e-6, 8, 1 << 16});
  EXPECT_NEAR(double(n[1]) / double(n[0]), 2.0, 0.05);
  EXPECT_LE(predicted_frame_mse(blocks, n), 1e-6);
}

TEST(SampleAllocation, NoCheaperCountsMeetTheTarget) {
  // Against brute force on a small grid: no allocation of lower cost predicts the target.
  const std::vector<BlockStat> blocks = {block(2e-3, 1.5, 1.5), block(5e-4, 1), block(6e-3, 3, 1.2)};
  const double target = 2e-4;
  const std::vector<uint32_t> n = allocate_samples(blocks, {target, 8, 512});
  ASSERT_LE(predicted_frame_mse(blocks, n), target);
  double cost = 0;
  for (size_t b = 0; b < 3; ++b) cost += blocks[b].cost * n[b];
  double best = 1e300;
  for (uint32_t a = 8; a <= 512; a += 8) {
    for (uint32_t b = 8; b <= 512; b += 8) {
      for (uint32_t c = 8; c <= 512; c += 8) {
        if (predicted_frame_mse(blocks, {a, b, c}) > target) continue;
        best = std::min(best, blocks[0].cost * a + blocks[1].cost * b + blocks[2].cost * c);
      }
    }
  }
  // Rounding each block up to an even count costs at most two samples per block over the optimum.
  EXPECT_LE(cost, best + 2 * (1.5 + 1 + 3));
}

TEST(SampleAllocation, BoundsHold) {
  const std::vector<BlockStat> blocks = {block(1e-2, 1, 1, 24), block(0, 1), block(1e-3, 1)};
  // Already met: every block keeps what it has (at least min_spp).
  EXPECT_EQ(allocate_samples(blocks, {1, 16, 64}), (std::vector<uint32_t>{24, 16, 16}));
  // Out of reach: everything to max_spp.
  EXPECT_EQ(allocate_samples(blocks, {1e-9, 8, 64}), (std::vector<uint32_t>{64, 64, 64}));
  // A block without error takes nothing more; counts are even (two equal streams) and never fall.
  const std::vector<uint32_t> n = allocate_samples(blocks, {1e-4, 8, 1024});
  EXPECT_EQ(n[1], 8u);
  EXPECT_GE(n[0], 24u);
  for (uint32_t c : n) EXPECT_EQ(c % 2, 0u);
}

}  // namespace
}  // namespace tessera

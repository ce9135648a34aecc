// SPDX-License-Identifier: Apache-2.0
#include "color/dither.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

namespace tessera::color {
namespace {

TEST(Dither, BayerMatrixIsTheStandardOne) {
  const int first_row[8] = {0, 32, 8, 40, 2, 34, 10, 42};
  for (int x = 0; x < 8; ++x) EXPECT_EQ(bayer_rank(x, 0), first_row[x]);
  EXPECT_EQ(bayer_rank(0, 1), 48);
  EXPECT_EQ(bayer_rank(1, 1), 16);
  std::vector<int> all;
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) all.push_back(bayer_rank(x, y));
  }
  std::sort(all.begin(), all.end());
  for (int i = 0; i < 64; ++i) EXPECT_EQ(all[size_t(i)], i);
}

TEST(Dither, BlueNoiseTileIsAPermutation) {
  std::vector<uint16_t> r = blue_noise_ranks();
  ASSERT_EQ(r.size(), size_t(kBlueNoiseSize * kBlueNoiseSize));
  std::sort(r.begin(), r.end());
  for (size_t i = 0; i < r.size(); ++i) ASSERT_EQ(r[i], i);
}

TEST(Dither, BlueNoiseIsEvenlySpread) {
  const auto& r = blue_noise_ranks();
  const int n = kBlueNoiseSize;
  auto on = [&](int x, int y, int count) {
    return r[size_t(((y + n) % n) * n + (x + n) % n)] < count;
  };
  // The first 10% of points: white noise would put ~80 of them next to each other;
  // void-and-cluster keeps them apart.
  int adjacent = 0;
  const int count = n * n / 10;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      if (on(x, y, count) && (on(x + 1, y, count) || on(x, y + 1, count))) ++adjacent;
    }
  }
  EXPECT_LE(adjacent, 4);
  // Every 8x8 window at 50% holds between 40% and 60% of its pixels.
  for (int wy = 0; wy < n; wy += 8) {
    for (int wx = 0; wx < n; wx += 8) {
      int c = 0;
      for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) c += on(wx + x, wy + y, n * n / 2);
      }
      EXPECT_GE(c, 26);
      EXPECT_LE(c, 38);
    }
  }
}

TEST(Dither, ThresholdsAreInsideTheUnitInterval) {
  for (auto d : {DitherMethod::kBayer, DitherMethod::kBlueNoise}) {
    double sum = 0.0;
    for (int y = 0; y < 64; ++y) {
      for (int x = 0; x < 64; ++x) {
        const float t = ordered_threshold(d, x, y);
        ASSERT_GT(t, 0.0f);
        ASSERT_LT(t, 1.0f);
        sum += t;
      }
    }
    EXPECT_NEAR(sum / 4096.0, 0.5, 1e-6);  // unbiased
  }
  EXPECT_EQ(ordered_threshold(DitherMethod::kNone, 3, 4), 0.5f);
  EXPECT_EQ(ordered_threshold(DitherMethod::kBlueNoise, -1, 0),
            ordered_threshold(DitherMethod::kBlueNoise, 63, 0));  // tiles
}

TEST(Dither, NamesRoundTrip) {
  for (auto d : {DitherMethod::kNone, DitherMethod::kBayer, DitherMethod::kBlueNoise,
                 DitherMethod::kFloydSteinberg}) {
    EXPECT_EQ(parse_dither(dither_name(d)), d);
  }
}

}  // namespace
}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
#include "math/next_float.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace tessera {
namespace {

// Bit for bit what std::nextafter gives, on the special values and on random bit patterns of
// every exponent (denormals, both signs, both zeros, the largest finite, infinities).
TEST(NextFloat, EqualsStdNextafterTowardBothInfinities) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  std::vector<float> values = {0.0f, -0.0f, 1.0f, -1.0f, inf, -inf, std::numeric_limits<float>::max(),
                               -std::numeric_limits<float>::max(), std::numeric_limits<float>::min(),
                               -std::numeric_limits<float>::min(), std::numeric_limits<float>::denorm_min(),
                               -std::numeric_limits<float>::denorm_min()};
  std::mt19937 rng(1);
  while (values.size() < 200000) {
    const float v = std::bit_cast<float>(uint32_t(rng()));
    if (!std::isnan(v)) values.push_back(v);
  }
  for (float v : values) {
    ASSERT_EQ(std::bit_cast<uint32_t>(next_float_up(v)), std::bit_cast<uint32_t>(std::nextafter(v, inf))) << v;
    ASSERT_EQ(std::bit_cast<uint32_t>(next_float_down(v)), std::bit_cast<uint32_t>(std::nextafter(v, -inf))) << v;
  }
  EXPECT_TRUE(std::isnan(next_float_up(std::numeric_limits<float>::quiet_NaN())));
  EXPECT_TRUE(std::isnan(next_float_down(std::numeric_limits<float>::quiet_NaN())));
}

}  // namespace
}  // namespace tessera

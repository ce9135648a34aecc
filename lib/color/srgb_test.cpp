// SPDX-License-Identifier: Apache-2.0
#include "color/srgb.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace tessera::color {
namespace {

TEST(Srgb, UsesTheExactIecConstants) {
  EXPECT_DOUBLE_EQ(srgb_encode(0.0031308), 12.92 * 0.0031308);
  EXPECT_DOUBLE_EQ(srgb_encode(0.001), 0.01292);
  EXPECT_DOUBLE_EQ(srgb_encode(0.5), 1.055 * std::pow(0.5, 1.0 / 2.4) - 0.055);
  EXPECT_DOUBLE_EQ(srgb_decode(0.04045), 0.04045 / 12.92);
  EXPECT_DOUBLE_EQ(srgb_decode(0.5), std::pow((0.5 + 0.055) / 1.055, 2.4));
  EXPECT_DOUBLE_EQ(srgb_encode(1.0), 1.0);
  // Published 8-bit values: 18% gray is code 118, linear 0.5 is 188, 0.0031308 is 10.
  EXPECT_EQ(linear_to_srgb8(0.18), 118);
  EXPECT_EQ(linear_to_srgb8(0.5), 188);
  EXPECT_EQ(linear_to_srgb8(0.0031308), 10);
}

TEST(Srgb, PiecesMeetAtTheBreakpoints) {
  // Both pieces evaluated at the threshold agree to the precision of the published constants.
  const double lin = 12.92 * 0.0031308;
  const double pow_piece = 1.055 * std::pow(0.0031308, 1.0 / 2.4) - 0.055;
  EXPECT_NEAR(lin, pow_piece, 1e-7);
  EXPECT_NEAR(srgb_encode(std::nextafter(0.0031308, 1.0)), srgb_encode(0.0031308), 1e-7);
  EXPECT_NEAR(srgb_decode(std::nextafter(0.04045, 1.0)), srgb_decode(0.04045), 1e-8);
}

TEST(Srgb, IsMonotonicAndInvertible) {
  double prev = -1.0;
  for (int i = 0; i <= 100000; ++i) {
    const double x = i / 100000.0;
    const double e = srgb_encode(x);
    ASSERT_GT(e, prev) << x;
    prev = e;
    ASSERT_NEAR(srgb_decode(e), x, 1e-12 + 1e-12 * x) << x;
  }
}

TEST(Srgb, EightBitTableRoundTrips) {
  const auto& t = srgb8_to_linear_table();
  for (int i = 0; i < 256; ++i) EXPECT_EQ(linear_to_srgb8(t[size_t(i)]), i);
  EXPECT_EQ(t[0], 0.0f);
  EXPECT_EQ(t[255], 1.0f);
}

TEST(Srgb, OutOfRangeAndNanAreClampedNotPropagated) {
  EXPECT_EQ(srgb_encode(std::numeric_limits<double>::quiet_NaN()), 0.0);
  EXPECT_EQ(srgb_encode(-1.0), 0.0);
  EXPECT_EQ(srgb_encode(7.0), 1.0);
  EXPECT_EQ(srgb_encode(std::numeric_limits<double>::infinity()), 1.0);
  EXPECT_EQ(linear_to_srgb8(std::numeric_limits<double>::quiet_NaN()), 0);
  EXPECT_EQ(linear_to_srgb8(1e30), 255);
}

}  // namespace
}  // namespace tessera::color

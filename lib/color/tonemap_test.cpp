// SPDX-License-Identifier: Apache-2.0
#include "color/tonemap.h"

#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <limits>

namespace tessera::color {
namespace {

Rgb gray(float v) { return {v, v, v}; }

TEST(ToneMap, ExposureIsPowerOfTwo) {
  EXPECT_DOUBLE_EQ(exposure_scale(0.0f), 1.0);
  EXPECT_DOUBLE_EQ(exposure_scale(1.0f), 2.0);
  EXPECT_DOUBLE_EQ(exposure_scale(-2.0f), 0.25);
  ImageRGB img(1, 1);
  img.rgb = {0.25f, 0.1f, 3.0f};
  const ImageRGB out = tonemap_image(img, {ToneMapOperator::kClamp, 1.0f, 0.0f});
  EXPECT_FLOAT_EQ(out.rgb[0], 0.5f);
  EXPECT_FLOAT_EQ(out.rgb[1], 0.2f);
  EXPECT_FLOAT_EQ(out.rgb[2], 1.0f);
}

TEST(ToneMap, ReinhardMapsWhiteToExactlyOne) {
  for (double w : {1.0, 2.5, 160.0, 1e4}) {
    const Rgb out = tonemap_reinhard(gray(float(w)), w);
    EXPECT_EQ(out.r, 1.0f) << w;
    EXPECT_LT(tonemap_reinhard(gray(float(w * 0.9)), w).r, 1.0f) << w;
  }
  // Extended Reinhard formula at a known point: x = 1, white = 4 -> 1 * (1 + 1/16) / 2.
  EXPECT_NEAR(tonemap_reinhard(gray(1.0f), 4.0).r, 0.53125, 1e-7);
  // Monotonic.
  float prev = -1.0f;
  for (int i = 0; i <= 1000; ++i) {
    const float v = tonemap_reinhard(gray(float(i) * 0.2f), 160.0).g;
    ASSERT_GE(v, prev);
    prev = v;
  }
}

TEST(ToneMap, ReinhardDefaultWhiteIsTheBrightestPixel) {
  ImageRGB img(2, 1);
  img.rgb = {160.0f, 0.5f, 0.0f, 1.0f, 2.0f, std::numeric_limits<float>::infinity()};
  double white = 0.0;
  const ImageRGB out = tonemap_image(img, {ToneMapOperator::kReinhard, 0.0f, 0.0f}, &white);
  EXPECT_EQ(white, 160.0);  // the Inf is not a finite value and does not count
  EXPECT_EQ(out.rgb[0], 1.0f);
  EXPECT_EQ(out.rgb[5], 1.0f);  // +Inf maps to white
  EXPECT_GT(out.rgb[1], 0.0f);
  EXPECT_LT(out.rgb[1], 0.5f);
}

TEST(ToneMap, PbrNeutralIsAnOffsetBelowTheCompressionStart) {
  // min >= 0.08: offset F90 = 0.04 is subtracted and nothing else while max - 0.04 <= 0.76.
  const Rgb in{0.1f, 0.5f, 0.79f};
  const Rgb out = tonemap_pbr_neutral(in);
  EXPECT_NEAR(out.r, 0.06, 1e-6);
  EXPECT_NEAR(out.g, 0.46, 1e-6);
  EXPECT_NEAR(out.b, 0.75, 1e-6);
  // min < 0.08: the toe. For a gray x the result is x - (x - 6.25 x^2) = 6.25 x^2.
  for (float x : {0.0f, 0.01f, 0.05f, 0.079f}) {
    EXPECT_NEAR(tonemap_pbr_neutral(gray(x)).r, 6.25 * x * x, 1e-7) << x;
  }
  // Continuous where compression starts (p = 0.76) and compressing above it.
  const float below = tonemap_pbr_neutral(gray(0.8f - 1e-5f)).r;
  const float above = tonemap_pbr_neutral(gray(0.8f + 1e-5f)).r;
  EXPECT_NEAR(below, above, 1e-4);
  EXPECT_LT(tonemap_pbr_neutral(gray(2.0f)).r, 2.0f - 0.04f);
  EXPECT_GT(tonemap_pbr_neutral(gray(2.0f)).r, 0.76f);
  EXPECT_NEAR(tonemap_pbr_neutral(gray(1e6f)).r, 1.0f, 1e-5);
}

TEST(ToneMap, PbrNeutralDesaturatesBrightColorsTowardWhite) {
  const Rgb out = tonemap_pbr_neutral({160.0f, 16.0f, 1.6f});
  EXPECT_GT(out.b, 0.5f);  // a 100:1 ratio is mostly gone
  EXPECT_LE(out.r, 1.0f);
}

TEST(ToneMap, AcesHillFitKnownValues) {
  EXPECT_EQ(tonemap_aces_hill(gray(0.0f)).r, 0.0f);  // the fit dips below 0 there: clamped
  // Mid gray through RRTAndODTFit: (0.18 (0.18 + 0.0245786) - 0.000090537) /
  // (0.18 (0.983729 0.18 + 0.4329510) + 0.238081) = 0.10559; the matrices keep gray gray.
  const Rgb mid = tonemap_aces_hill(gray(0.18f));
  EXPECT_NEAR(mid.r, 0.10559, 2e-4);
  EXPECT_NEAR(mid.g, mid.r, 1e-4);
  EXPECT_NEAR(mid.b, mid.r, 1e-4);
  EXPECT_EQ(tonemap_aces_hill(gray(1e4f)).g, 1.0f);
  float prev = -1.0f;
  for (int i = 0; i <= 2000; ++i) {
    const float v = tonemap_aces_hill(gray(float(i) * 0.01f)).g;
    ASSERT_GE(v, prev);
    prev = v;
  }
}

TEST(ToneMap, SpecialInputsGiveFiniteResultsForEveryOperator) {
  ImageRGB img(6, 1);
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  img.rgb = {nan, nan, -inf, inf, -5.0f, FLT_MAX, 1e30f, 0.5f, 0.5f,
             0.0f, -0.0f, 160.0f, inf, inf, inf, -1e-30f, 1e-30f, 0.0f};
  for (auto op : {ToneMapOperator::kClamp, ToneMapOperator::kReinhard, ToneMapOperator::kAces,
                  ToneMapOperator::kPbrNeutral}) {
    for (float ev : {-10.0f, 0.0f, 20.0f}) {
      const ImageRGB out = tonemap_image(img, {op, ev, 0.0f});
      for (float v : out.rgb) {
        ASSERT_TRUE(std::isfinite(v)) << tonemap_name(op);
        ASSERT_GE(v, 0.0f);
        ASSERT_LE(v, 1.0f);
      }
      // NaN and -Inf are black; a pure +Inf pixel is white.
      EXPECT_EQ(out.rgb[0], 0.0f);
      EXPECT_EQ(out.rgb[1], 0.0f);
      EXPECT_EQ(out.rgb[2], 0.0f);
      EXPECT_NEAR(out.rgb[12], 1.0f, 1e-5) << tonemap_name(op);
    }
  }
}

TEST(ToneMap, NamesRoundTrip) {
  for (auto op : {ToneMapOperator::kClamp, ToneMapOperator::kReinhard, ToneMapOperator::kAces,
                  ToneMapOperator::kPbrNeutral}) {
    EXPECT_EQ(parse_tonemap(tonemap_name(op)), op);
  }
  EXPECT_FALSE(parse_tonemap("filmic").has_value());
}

}  // namespace
}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
#include "color/image_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tessera::color {
namespace {

TEST(ImageMetrics, PsnrOfKnownErrors) {
  ImageRGB a(4, 4), b(4, 4);
  for (float& v : a.rgb) v = 0.5f;
  for (float& v : b.rgb) v = 0.5f + 1.0f / 255.0f;  // one code value everywhere: MSE 1
  const LdrError e = ldr_error(a, b);
  EXPECT_NEAR(e.psnr_db, 20.0 * std::log10(255.0), 1e-4);  // 48.13 dB
  EXPECT_NEAR(e.max_abs, 1.0, 1e-4);
  EXPECT_NEAR(e.rmse, 1.0, 1e-4);
  EXPECT_TRUE(std::isinf(ldr_error(a, a).psnr_db));
  EXPECT_THROW(ldr_error(a, ImageRGB(2, 2)), std::exception);
}

TEST(ImageMetrics, RelativeErrorIsAgainstTheLargestChannel) {
  ImageRGB ref(2, 1), dec(2, 1);
  ref.rgb = {100.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  dec.rgb = {101.0f, 1.5f, 0.0f, 0.0f, 0.0f, 1e-7f};
  const HdrError e = hdr_relative_error(ref, dec);
  EXPECT_NEAR(e.max_rel, 0.01, 1e-7);  // 1 / 100, the 0.5 on a small channel counts as 0.5/100
  // The black pixel: 1e-6 against the 2^-14 floor.
  EXPECT_NEAR(e.mean_rel, (0.01 + 1e-7 / 0x1p-14) / 2.0, 1e-7);
  const std::vector<uint8_t> only_first = {1, 0};
  EXPECT_NEAR(hdr_relative_error(ref, dec, &only_first).mean_rel, 0.01, 1e-7);
  EXPECT_NEAR(ldr_error(ref, dec, &only_first).max_abs, 255.0, 1e-3);
}

TEST(ImageMetrics, LowFrequencyErrorSeesBiasNotNoise) {
  ImageRGB ref(32, 32), offset(32, 32), checker(32, 32);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) {
      for (int c = 0; c < 3; ++c) {
        offset.at(x, y)[c] = 0.1f;
        checker.at(x, y)[c] = (x + y) % 2 ? 0.1f : -0.1f;
      }
    }
  }
  EXPECT_NEAR(low_frequency_error(ref, offset, 3), 0.1, 1e-6);
  EXPECT_LT(low_frequency_error(ref, checker, 3), 0.01);
}

}  // namespace
}  // namespace tessera::color

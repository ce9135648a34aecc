// SPDX-License-Identifier: Apache-2.0
// exr-half goes through OpenEXR's half (round to nearest even): check the bound the format
// guarantees in its normal range, on values a render has.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "image/exr_io.h"

namespace tessera::color {
namespace {

TEST(Half, RoundTripWithinTwoToTheMinusElevenInNormalRange) {
  ImageRGB img(256, 128);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> log_mag(std::log2(6.2e-5f), std::log2(65504.0f));
  for (float& v : img.rgb) v = std::exp2(log_mag(rng));
  img.rgb[0] = 160.0f;
  img.rgb[1] = 1e4f;
  img.rgb[2] = 65504.0f;
  const auto path = std::filesystem::temp_directory_path() / "tessera_half_test.exr";
  write_exr(path.string(), img, {}, ExrPixelType::kHalf);
  const ImageRGB back = read_exr(path.string());
  ASSERT_EQ(back.rgb.size(), img.rgb.size());
  for (size_t i = 0; i < img.rgb.size(); ++i) {
    ASSERT_LE(std::abs(back.rgb[i] - img.rgb[i]), 0x1p-11 * img.rgb[i]) << img.rgb[i];
  }
  EXPECT_EQ(back.rgb[0], 160.0f);
  EXPECT_EQ(back.rgb[1], 10000.0f);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace tessera::color

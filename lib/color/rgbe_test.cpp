// SPDX-License-Identifier: Apache-2.0
#include "color/rgbe.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>

namespace tessera::color {
namespace {

TEST(Rgbe, RoundTripWithinTwoToTheMinusEight) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> log_mag(-60.0f, 100.0f);  // 1e-18 .. 1e30
  std::uniform_real_distribution<float> frac(0.0f, 1.0f);
  std::vector<Rgb> colors = {{160.0f, 160.0f, 160.0f}, {1e4f, 20.0f, 0.1f}, {1.0f, 0.5f, 0.25f}};
  while (colors.size() < 200000) {
    const float m = std::exp2(log_mag(rng));
    Rgb c{m * frac(rng), m * frac(rng), m * frac(rng) * frac(rng)};
    c[int(rng() % 3)] = m;
    colors.push_back(c);
  }
  for (const Rgb& c : colors) {
    const Rgb d = decode_rgbe(encode_rgbe(c));
    const double m = c.max_component();
    ASSERT_LE(std::abs(double(d.max_component()) - m), 0x1p-8 * m) << c.r << " " << c.g;
    for (int k = 0; k < 3; ++k) ASSERT_LE(std::abs(double(d[k]) - c[k]), 0x1p-8 * m);
  }
}

TEST(Rgbe, KnownEncodingsAndRounding) {
  EXPECT_EQ(encode_rgbe({1.0f, 1.0f, 1.0f}), (Rgbe{128, 128, 128, 129}));
  EXPECT_EQ(encode_rgbe({0.5f, 0.25f, 0.0f}), (Rgbe{128, 64, 0, 128}));
  // 1 - 2^-10: mantissa 255.75 would round to 256; it is capped at 255 (error 0.75/256).
  const float v = 1.0f - 0x1p-10f;
  EXPECT_EQ(encode_rgbe({v, v, 0.0f}), (Rgbe{255, 255, 0, 128}));
  EXPECT_EQ(encode_rgbe({255.4f / 256.0f, 0.0f, 0.0f}), (Rgbe{255, 0, 0, 128}));
  EXPECT_EQ(encode_rgbe({254.4f / 256.0f, 0.0f, 0.0f}), (Rgbe{254, 0, 0, 128}));
  EXPECT_EQ(decode_rgbe({128, 128, 128, 129}).r, 1.0f);
  EXPECT_EQ(decode_rgbe({200, 1, 1, 0}).r, 0.0f);  // exponent 0 is black
}

TEST(Rgbe, SpecialValuesAreClampedDeterministically) {
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(encode_rgbe({inf, 0.0f, 0.0f}), (Rgbe{255, 0, 0, 255}));
  EXPECT_EQ(encode_rgbe({nan, -1.0f, -inf}), (Rgbe{0, 0, 0, 0}));
  EXPECT_EQ(encode_rgbe({1e-40f, 0.0f, 0.0f}), (Rgbe{0, 0, 0, 0}));
  EXPECT_DOUBLE_EQ(double(decode_rgbe(encode_rgbe({3e38f, 0, 0})).r), kRgbeMax);
}

class RadianceFile : public ::testing::TestWithParam<int> {};

TEST_P(RadianceFile, RoundTripsRunLengthEncodedAndFlat) {
  const int w = GetParam(), h = 4;
  std::vector<Rgbe> px(size_t(w) * h);
  std::mt19937 rng(static_cast<uint32_t>(w));
  for (size_t i = 0; i < px.size(); ++i) {
    // Long runs (sky), short runs and noise, to exercise every RLE branch.
    const float v = i % 40 < 20 ? 0.75f : float(rng() % 1000) * 0.01f + float((i / 3) % 2);
    px[i] = encode_rgbe({v, v * 0.5f, i % 40 < 20 ? 0.1f : float(i % 7)});
  }
  const auto path = std::filesystem::temp_directory_path() / ("tessera_rgbe_" + std::to_string(w) + ".hdr");
  write_radiance_hdr(path.string(), w, h, px);
  std::ifstream f(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.rfind("#?RADIANCE\n", 0), 0u);
  EXPECT_NE(text.find("FORMAT=32-bit_rle_rgbe\n\n-Y 4 +X " + std::to_string(w) + "\n"),
            std::string::npos);
  int rw = 0, rh = 0;
  EXPECT_EQ(read_radiance_hdr(path.string(), &rw, &rh), px);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
  if (w >= 100) {
    EXPECT_LT(text.size(), px.size() * 4);  // the runs did compress
  }
  std::filesystem::remove(path);
}

INSTANTIATE_TEST_SUITE_P(Widths, RadianceFile, ::testing::Values(1, 5, 8, 300));

}  // namespace
}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
#include "color/rgb9e5.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>

#include "color/dds_rgb9e5.h"

namespace tessera::color {
namespace {

// Random colors whose largest channel spans 2^-15 (the smallest normal RGB9E5 exponent) to
// 65408, log-uniformly, plus the values a render actually has.
std::vector<Rgb> random_colors(uint32_t seed, float lo, float hi, size_t n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> log_mag(std::log2(lo), std::log2(hi));
  std::uniform_real_distribution<float> frac(0.0f, 1.0f);
  std::vector<Rgb> out;
  for (float v : {160.0f, 1e4f, 1.0f, 0.5f, 65408.0f, 1e-4f}) {
    out.push_back({v, v, v});
    out.push_back({v, v * 0.3f, v * 1e-3f});
  }
  while (out.size() < n) {
    const float m = std::exp2(log_mag(rng));
    Rgb c{m * frac(rng), m * frac(rng) * frac(rng), m * std::exp2(-20.0f * frac(rng))};
    c[int(rng() % 3)] = m;  // the largest channel is exactly m
    out.push_back(c);
  }
  return out;
}

TEST(Rgb9e5, RoundTripWithinTheSpecBound) {
  // Largest channel: relative error <= 2^-9. Others share its step, half of which is at most
  // 2^-9 of the larger of the largest channel and its decoded value (after a rounding carry
  // the decoded value is the larger).
  for (const Rgb& c : random_colors(9, 0x1p-15f, 65408.0f, 200000)) {
    const Rgb d = decode_rgb9e5(encode_rgb9e5(c));
    const float m = c.max_component();
    int largest = 0;
    for (int k = 1; k < 3; ++k) largest = c[k] > c[largest] ? k : largest;
    ASSERT_LE(std::abs(d[largest] - m), 0x1p-9 * m) << c.r << " " << c.g << " " << c.b;
    const float step_bound = 0x1p-9f * std::max(m, d.max_component());
    for (int k = 0; k < 3; ++k) ASSERT_LE(std::abs(d[k] - c[k]), step_bound) << k;
  }
}

TEST(Rgb9e5, BitLayoutMatchesGlRgb9E5) {
  // 1.0: floor(log2(1)) = 0, exponent 0 + 1 + 15 = 16, mantissa 1 / 2^(16-15-9) = 256.
  EXPECT_EQ(encode_rgb9e5({1.0f, 0.0f, 0.0f}), 256u | 16u << 27);
  EXPECT_EQ(encode_rgb9e5({0.0f, 1.0f, 0.0f}), 256u << 9 | 16u << 27);
  EXPECT_EQ(encode_rgb9e5({0.0f, 0.0f, 1.0f}), 256u << 18 | 16u << 27);
  EXPECT_EQ(encode_rgb9e5({0.0f, 0.0f, 0.0f}), 0u);
  const Rgb d = decode_rgb9e5(0x1ffu | 0x1ffu << 9 | 0x1ffu << 18 | 31u << 27);
  EXPECT_EQ(d.r, 65408.0f);
  EXPECT_EQ(d.b, 65408.0f);
}

TEST(Rgb9e5, ClampsToSharedExpMax) {
  EXPECT_EQ(kRgb9e5Max, 511.0f / 512.0f * 65536.0f);
  for (float v : {65408.0f, 65500.0f, 1e5f, 1e30f, std::numeric_limits<float>::infinity()}) {
    const Rgb d = decode_rgb9e5(encode_rgb9e5({v, 2.0f, 0.0f}));
    EXPECT_EQ(d.r, 65408.0f) << v;
    EXPECT_EQ(encode_rgb9e5({v, 0.0f, 0.0f}) >> 27, 31u) << v;
  }
}

TEST(Rgb9e5, RoundingCarryIncrementsTheExponent) {
  // 1 - 2^-11: exp_shared' = 15, max_s = floor(511.75 + 0.5) = 512 = 2^N -> exponent 16,
  // mantissa round(0.99951 * 256) = 256, i.e. exactly 1.0.
  const float v = 1.0f - 0x1p-11f;
  const uint32_t p = encode_rgb9e5({v, v, v});
  EXPECT_EQ(p >> 27, 16u);
  EXPECT_EQ(p & 0x1ff, 256u);
  EXPECT_EQ(decode_rgb9e5(p).g, 1.0f);
  // Just below the carry: 1 - 2^-9 -> 511 at exponent 15, no carry.
  const uint32_t q = encode_rgb9e5({1.0f - 0x1p-9f, 0.0f, 0.0f});
  EXPECT_EQ(q >> 27, 15u);
  EXPECT_EQ(q & 0x1ff, 511u);
  // The carry at the top of the range: 65407.9 rounds into 65408 without overflow.
  EXPECT_EQ(decode_rgb9e5(encode_rgb9e5({65407.9f, 0.0f, 0.0f})).r, 65408.0f);
}

TEST(Rgb9e5, TinyNegativeAndNanValues) {
  EXPECT_EQ(encode_rgb9e5({0x1p-24f, 0.0f, 0.0f}), 1u);  // smallest step: exponent 0
  EXPECT_EQ(encode_rgb9e5({0x1p-26f, 0.0f, 0.0f}), 0u);  // rounds to zero
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const Rgb d = decode_rgb9e5(encode_rgb9e5({nan, -3.0f, 2.0f}));
  EXPECT_EQ(d.r, 0.0f);
  EXPECT_EQ(d.g, 0.0f);
  EXPECT_EQ(d.b, 2.0f);
  EXPECT_EQ(decode_rgb9e5(encode_rgb9e5({-std::numeric_limits<float>::infinity(), 0, 0})).r, 0.0f);
}

uint32_t le32(const std::vector<uint8_t>& d, size_t at) {
  return uint32_t(d[at]) | uint32_t(d[at + 1]) << 8 | uint32_t(d[at + 2]) << 16 |
         uint32_t(d[at + 3]) << 24;
}

TEST(DdsRgb9e5, HeaderFollowsTheDx10LayoutAndTexelsRoundTrip) {
  const int w = 5, h = 3;
  std::vector<uint32_t> texels;
  for (int i = 0; i < w * h; ++i) texels.push_back(encode_rgb9e5({float(i) * 10.0f, 1.0f, 0.25f}));
  const auto path = std::filesystem::temp_directory_path() / "tessera_rgb9e5_test.dds";
  write_dds_rgb9e5(path.string(), w, h, texels);
  std::ifstream f(path, std::ios::binary);
  const std::vector<uint8_t> d((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(d.size(), 148u + 4u * w * h);
  EXPECT_EQ(std::string(d.begin(), d.begin() + 4), "DDS ");
  EXPECT_EQ(le32(d, 4), 124u);          // dwSize
  EXPECT_EQ(le32(d, 12), uint32_t(h));  // dwHeight
  EXPECT_EQ(le32(d, 16), uint32_t(w));  // dwWidth
  EXPECT_EQ(le32(d, 20), uint32_t(w) * 4);  // pitch
  EXPECT_EQ(le32(d, 76), 32u);          // ddspf.dwSize
  EXPECT_EQ(le32(d, 80), 0x4u);         // DDPF_FOURCC
  EXPECT_EQ(std::string(d.begin() + 84, d.begin() + 88), "DX10");
  EXPECT_EQ(le32(d, 108), 0x1000u);     // DDSCAPS_TEXTURE
  EXPECT_EQ(le32(d, 128), 67u);         // DXGI_FORMAT_R9G9B9E5_SHAREDEXP
  EXPECT_EQ(le32(d, 132), 3u);          // D3D10_RESOURCE_DIMENSION_TEXTURE2D
  EXPECT_EQ(le32(d, 140), 1u);          // arraySize
  EXPECT_EQ(le32(d, 148), texels[0]);
  int rw = 0, rh = 0;
  EXPECT_EQ(read_dds_rgb9e5(path.string(), &rw, &rh), texels);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace tessera::color

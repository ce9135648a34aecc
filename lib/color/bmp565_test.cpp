// SPDX-License-Identifier: Apache-2.0
#include "color/bmp565.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include "color/image_metrics.h"
#include "color/srgb.h"

namespace tessera::color {
namespace {

TEST(Bmp565, PacksFiveSixFive) {
  EXPECT_EQ(pack_565({1.0f, 1.0f, 1.0f}, 0.5f), 0xFFFF);
  EXPECT_EQ(pack_565({1.0f, 0.0f, 0.0f}, 0.5f), 0xF800);
  EXPECT_EQ(pack_565({0.0f, 1.0f, 0.0f}, 0.5f), 0x07E0);
  EXPECT_EQ(pack_565({0.0f, 0.0f, 1.0f}, 0.5f), 0x001F);
  // Rounding: 0.5 * 31 = 15.5 -> 16, 0.5 * 63 = 31.5 -> 32.
  EXPECT_EQ(pack_565({0.5f, 0.5f, 0.5f}, 0.5f), 16 << 11 | 32 << 5 | 16);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(pack_565({nan, -1.0f, 7.0f}, 0.5f), 0x001F);
  const Rgb d = unpack_565(0xFFFF);
  EXPECT_EQ(d.r, 1.0f);
  EXPECT_EQ(d.g, 1.0f);
}

TEST(Bmp565, FileHasBitfieldsMasksAndRoundTrips) {
  const int w = 5, h = 3;  // 10-byte rows padded to 12
  std::vector<uint16_t> px;
  for (int i = 0; i < w * h; ++i) px.push_back(uint16_t(i * 4099));
  const auto path = std::filesystem::temp_directory_path() / "tessera_565.bmp";
  write_bmp565(path.string(), w, h, px);
  std::ifstream f(path, std::ios::binary);
  const std::vector<uint8_t> d((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  auto le32 = [&](size_t at) {
    return uint32_t(d[at]) | uint32_t(d[at + 1]) << 8 | uint32_t(d[at + 2]) << 16 | uint32_t(d[at + 3]) << 24;
  };
  ASSERT_EQ(d.size(), 14u + 108u + 12u * h);
  EXPECT_EQ(d[0], 'B');
  EXPECT_EQ(le32(2), d.size());
  EXPECT_EQ(le32(10), 122u);     // pixel data offset
  EXPECT_EQ(le32(14), 108u);     // BITMAPV4HEADER
  EXPECT_EQ(d[28], 16);          // bits per pixel
  EXPECT_EQ(le32(30), 3u);       // BI_BITFIELDS
  EXPECT_EQ(le32(54), 0xF800u);  // red mask
  EXPECT_EQ(le32(58), 0x07E0u);  // green mask
  EXPECT_EQ(le32(62), 0x001Fu);  // blue mask
  EXPECT_EQ(le32(70), 0x73524742u);  // LCS_sRGB
  // Bottom-up: the file's first row is the image's last.
  EXPECT_EQ(uint32_t(d[122]) | uint32_t(d[123]) << 8, px[size_t(w * (h - 1))]);
  int rw = 0, rh = 0;
  EXPECT_EQ(read_bmp565(path.string(), &rw, &rh), px);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
  std::filesystem::remove(path);
}

// A slow dark ramp, the classic banding case for 5 bits.
ImageRGB dark_ramp(int w, int h) {
  ImageRGB img(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = 0.02f + 0.10f * float(x) / float(w - 1);
      float* p = img.at(x, y);
      p[0] = v;
      p[1] = v * 0.9f;
      p[2] = v * 1.1f;
    }
  }
  return img;
}

ImageRGB decode_linear(const std::vector<uint16_t>& px, int w, int h) {
  ImageRGB out(w, h);
  for (size_t i = 0; i < px.size(); ++i) {
    const Rgb e = unpack_565(px[i]);
    for (int c = 0; c < 3; ++c) out.rgb[3 * i + size_t(c)] = float(srgb_decode(e[c]));
  }
  return out;
}

TEST(Bmp565, OrderedDitherReducesBanding) {
  const int w = 256, h = 64;
  const ImageRGB linear = dark_ramp(w, h);
  const ImageRGB srgb = srgb_encode_image(linear);
  auto banding = [&](DitherMethod d) {
    return low_frequency_error(linear, decode_linear(quantize_565(srgb, d), w, h), 4);
  };
  const double none = banding(DitherMethod::kNone);
  const double bayer = banding(DitherMethod::kBayer);
  const double blue = banding(DitherMethod::kBlueNoise);
  EXPECT_LT(bayer, 0.35 * none) << none << " " << bayer;
  EXPECT_LT(blue, 0.35 * none) << none << " " << blue;
  EXPECT_THROW(quantize_565(srgb, DitherMethod::kFloydSteinberg), std::exception);
}

}  // namespace
}  // namespace tessera::color

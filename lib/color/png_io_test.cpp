// SPDX-License-Identifier: Apache-2.0
#include "color/png_io.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "color/color_error.h"

#include <unistd.h>

namespace tessera::color {
namespace {

// Per process: ctest -j runs each parameterized case in its own process at the same time.
std::string temp(const std::string& name) {
  return (std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_" + name)).string();
}

TEST(PngIo, TruecolorRoundTrips) {
  Rgb8Image img;
  img.width = 7;
  img.height = 3;
  for (int i = 0; i < 7 * 3 * 3; ++i) img.pixels.push_back(uint8_t(i * 11));
  const std::string path = temp("tessera_png_rgb.png");
  write_png(path, img);
  const Rgb8Image back = read_png_rgb8(path);
  EXPECT_EQ(back.width, 7);
  EXPECT_EQ(back.height, 3);
  EXPECT_EQ(back.pixels, img.pixels);
  std::filesystem::remove(path);
}

TEST(PngIo, RgbaIsReadBackWithoutAlpha) {
  Rgb8Image img;
  img.width = 2;
  img.height = 1;
  img.channels = 4;
  img.pixels = {1, 2, 3, 255, 4, 5, 6, 255};
  const std::string path = temp("tessera_png_rgba.png");
  write_png(path, img);
  EXPECT_EQ(read_png_rgb8(path).pixels, (std::vector<uint8_t>{1, 2, 3, 4, 5, 6}));
  std::filesystem::remove(path);
}

class IndexedDepth : public ::testing::TestWithParam<std::pair<int, int>> {};

TEST_P(IndexedDepth, RoundTripsIndicesPaletteAndDepth) {
  const auto [colors, depth] = GetParam();
  IndexedImage img;
  img.width = 13;  // odd width: packed rows end mid-byte
  img.height = 5;
  for (int i = 0; i < colors; ++i) img.palette.push_back({uint8_t(i), uint8_t(255 - i), uint8_t(i * 7)});
  for (int i = 0; i < 13 * 5; ++i) img.indices.push_back(uint8_t((i * 31) % colors));
  const std::string path = temp("tessera_png_indexed.png");
  write_png_indexed(path, img);
  int bit_depth = 0;
  const IndexedImage back = read_png_indexed(path, &bit_depth);
  EXPECT_EQ(bit_depth, depth);
  EXPECT_EQ(back.indices, img.indices);
  EXPECT_EQ(back.palette, img.palette);
  // And a generic reader expands the palette.
  const Rgb8Image rgb = read_png_rgb8(path);
  EXPECT_EQ(rgb.pixels[3 * 4], img.palette[img.indices[4]].r);
  std::filesystem::remove(path);
}

INSTANTIATE_TEST_SUITE_P(Depths, IndexedDepth,
                         ::testing::Values(std::pair{2, 1}, std::pair{4, 2}, std::pair{16, 4},
                                           std::pair{17, 8}, std::pair{256, 8}));

TEST(PngIo, ErrorsNameThePath) {
  try {
    read_png_rgb8("/nonexistent/tessera.png");
    FAIL();
  } catch (const ColorError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/tessera.png"), std::string::npos);
  }
  Rgb8Image img;
  img.width = img.height = 1;
  img.pixels = {0, 0, 0};
  const std::string path = temp("tessera_png_truecolor.png");
  write_png(path, img);
  EXPECT_THROW(read_png_indexed(path), ColorError);  // not a palette PNG
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace tessera::color

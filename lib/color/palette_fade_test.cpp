// SPDX-License-Identifier: Apache-2.0
#include "color/palette_fade.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "color/palette_quantizer.h"
#include "color/png_io.h"
#include "color/srgb.h"
#include "support/synthetic_images.h"
#include "color/tonemap.h"

namespace tessera::color {
namespace {

// PNG chunks by type (concatenated data of repeated types such as IDAT).
std::map<std::string, std::string> png_chunks(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  const std::string d((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::map<std::string, std::string> chunks;
  size_t pos = 8;
  while (pos + 12 <= d.size()) {
    const uint32_t len = uint32_t(uint8_t(d[pos])) << 24 | uint32_t(uint8_t(d[pos + 1])) << 16 |
                         uint32_t(uint8_t(d[pos + 2])) << 8 | uint32_t(uint8_t(d[pos + 3]));
    chunks[d.substr(pos + 4, 4)] += d.substr(pos + 8, len);
    pos += 12 + len;
  }
  return chunks;
}

TEST(PaletteFade, FramePaths) {
  EXPECT_EQ(frame_path("out_####.png", 3), "out_0003.png");
  EXPECT_EQ(frame_path("dir.v2/out_##.png", 100), "dir.v2/out_100.png");
  EXPECT_EQ(frame_path("fade.png", 12), "fade_0012.png");
  EXPECT_EQ(frame_path("dir.v2/fade", 1), "dir.v2/fade_0001");
}

TEST(PaletteFade, FadesInLinearLight) {
  const std::vector<Srgb8> p = {{255, 255, 255}, {188, 10, 0}};
  EXPECT_EQ(fade_palette(p, 1.0), p);
  EXPECT_EQ(fade_palette(p, 0.0), (std::vector<Srgb8>{{0, 0, 0}, {0, 0, 0}}));
  const auto half = fade_palette(p, 0.5);
  EXPECT_EQ(half[0].r, 188);  // half the light of white is code 188, not 128
}

TEST(PaletteFade, OnlyThePaletteChangesIndicesStayByteIdentical) {
  const auto dir = std::filesystem::temp_directory_path() / "tessera_fade_test";
  std::filesystem::create_directories(dir);
  const ImageRGB display =
      tonemap_image(make_render_like(64, 48), {ToneMapOperator::kAces, 0.0f, 0.0f});
  for (int colors : {256, 16}) {  // 8-bit and 4-bit indices
    const IndexedImage q = quantize_palette(display, {colors, DitherMethod::kFloydSteinberg, 16});
    const std::string in = (dir / "in.png").string();
    write_png_indexed(in, q);
    const auto written = write_palette_fade(in, 5, (dir / "f_####.png").string());
    ASSERT_EQ(written.size(), 5u);
    EXPECT_EQ(written[0], (dir / "f_0001.png").string());
    const auto in_chunks = png_chunks(in);
    int in_depth = 0;
    const IndexedImage original = read_png_indexed(in, &in_depth);
    for (size_t f = 0; f < written.size(); ++f) {
      int depth = 0;
      const IndexedImage frame = read_png_indexed(written[f], &depth);
      EXPECT_EQ(depth, in_depth);
      EXPECT_EQ(frame.indices, original.indices) << f;
      const auto chunks = png_chunks(written[f]);
      EXPECT_EQ(chunks.at("IDAT"), in_chunks.at("IDAT")) << f;  // the pixel data, byte for byte
      EXPECT_EQ(chunks.at("IHDR"), in_chunks.at("IHDR")) << f;
      ASSERT_EQ(frame.palette.size(), original.palette.size());
      const double factor = 1.0 - double(f) / 4.0;
      for (size_t i = 0; i < frame.palette.size(); ++i) {
        const Rgb a = srgb8_to_linear(original.palette[i]), b = srgb8_to_linear(frame.palette[i]);
        for (int c = 0; c < 3; ++c) {
          // Within half an 8-bit step of the exact linear fade.
          EXPECT_NEAR(b[c], a[c] * factor, 0.01 * a[c] + 0.0005) << f << " " << i;
        }
      }
    }
    EXPECT_NE(png_chunks(written[2]).at("PLTE"), in_chunks.at("PLTE"));
    for (const Srgb8& c : read_png_indexed(written.back()).palette) EXPECT_EQ(c, (Srgb8{0, 0, 0}));
  }
  EXPECT_THROW(write_palette_fade((dir / "in.png").string(), 1, (dir / "x_#.png").string()),
               std::exception);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace tessera::color

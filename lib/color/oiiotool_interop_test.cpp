// SPDX-License-Identifier: Apache-2.0
// An independent reader agrees with us: OpenImageIO's oiiotool decodes each file we write,
// and its pixels match the ones we say we wrote. Skipped (with a message) without oiiotool.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "color/bmp565.h"
#include "color/color_convert.h"
#include "color/png_io.h"
#include "color/rgb9e5.h"
#include "color/dds_rgb9e5.h"
#include "color/rgbe.h"
#include "support/synthetic_images.h"
#include "image/exr_io.h"

namespace tessera::color {
namespace {

bool have_oiiotool() {
  static const bool have = std::system("oiiotool --version > /dev/null 2>&1") == 0;
  return have;
}

// oiiotool IN -d float -o OUT.exr, then our EXR reader (itself tested against OpenEXR).
bool oiiotool_to_exr(const std::string& in, const std::string& out) {
  const std::string cmd = "oiiotool '" + in + "' -d float -o '" + out + "' > /dev/null 2>&1";
  return std::system(cmd.c_str()) == 0;
}

class OiiotoolInterop : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_oiiotool()) GTEST_SKIP() << "oiiotool not installed (apt-get install openimageio-tools)";
    dir_ = std::filesystem::temp_directory_path() /
           ("tessera_oiio_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::create_directories(dir_);
    hdr_ = make_render_like(96, 64);
  }
  void TearDown() override {
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Converts with our code, decodes with oiiotool, returns oiiotool's float pixels.
  ImageRGB via_oiiotool(OutputFormat f, const std::string& file, DitherMethod d = DitherMethod::kNone) {
    ConvertOptions o;
    o.format = f;
    o.tonemap.op = ToneMapOperator::kPbrNeutral;
    o.dither = d;
    convert_image(hdr_, path(file), o);
    EXPECT_TRUE(oiiotool_to_exr(path(file), path(file + ".exr"))) << "oiiotool could not read " << file;
    const ImageRGB img = read_exr(path(file + ".exr"));
    EXPECT_EQ(img.width, hdr_.width);
    EXPECT_EQ(img.height, hdr_.height);
    return img;
  }

  std::filesystem::path dir_;
  ImageRGB hdr_;
};

void expect_close(const ImageRGB& oiio, const ImageRGB& ours, double tolerance, double relative = 0.0) {
  ASSERT_EQ(oiio.rgb.size(), ours.rgb.size());
  double worst = 0.0;
  for (size_t i = 0; i < ours.rgb.size(); ++i) {
    const double d = std::abs(double(oiio.rgb[i]) - double(ours.rgb[i]));
    const double allowed = tolerance + relative * std::abs(double(ours.rgb[i]));
    worst = std::max(worst, d - allowed);
    ASSERT_LE(d, allowed) << "sample " << i << ": oiiotool " << oiio.rgb[i] << " vs ours " << ours.rgb[i];
  }
}

ImageRGB from_rgb8(const Rgb8Image& png) {
  ImageRGB out(png.width, png.height);
  for (size_t i = 0; i < out.rgb.size(); ++i) out.rgb[i] = float(png.pixels[i]) / 255.0f;
  return out;
}

TEST_F(OiiotoolInterop, PngTruecolorAndRgba) {
  for (auto f : {OutputFormat::kRgb8, OutputFormat::kRgba8}) {
    const std::string file = std::string(format_name(f)) + ".png";
    const ImageRGB oiio = via_oiiotool(f, file, DitherMethod::kBlueNoise);
    expect_close(oiio, from_rgb8(read_png_rgb8(path(file))), 1e-6);
  }
}

TEST_F(OiiotoolInterop, PalettePng) {
  const ImageRGB oiio = via_oiiotool(OutputFormat::kPalette, "pal.png");
  expect_close(oiio, from_rgb8(read_png_rgb8(path("pal.png"))), 1e-6);
  // And the PNG really is indexed.
  EXPECT_LE(read_png_indexed(path("pal.png")).palette.size(), 256u);
}

TEST_F(OiiotoolInterop, Bmp565) {
  const ImageRGB oiio = via_oiiotool(OutputFormat::kRgb565, "c.bmp", DitherMethod::kBayer);
  int w = 0, h = 0;
  const auto px = read_bmp565(path("c.bmp"), &w, &h);
  ImageRGB ours(w, h);
  for (size_t i = 0; i < px.size(); ++i) {
    const Rgb c = unpack_565(px[i]);
    for (int k = 0; k < 3; ++k) ours.rgb[3 * i + size_t(k)] = c[k];
  }
  // Readers widen 5/6 bits to 8 differently (OpenImageIO replicates the top bits:
  // v << 3 | v >> 2), which lands within one 8-bit step of v / 31.
  expect_close(oiio, ours, 1.0 / 255.0 + 1e-6);
}

TEST_F(OiiotoolInterop, RadianceHdr) {
  const ImageRGB oiio = via_oiiotool(OutputFormat::kRgbe, "e.hdr");
  int w = 0, h = 0;
  const auto px = read_radiance_hdr(path("e.hdr"), &w, &h);
  ImageRGB ours(w, h);
  for (size_t i = 0; i < px.size(); ++i) {
    const Rgb c = decode_rgbe(px[i]);
    for (int k = 0; k < 3; ++k) ours.rgb[3 * i + size_t(k)] = c[k];
  }
  expect_close(oiio, ours, 0.0, 1e-7);  // same m * 2^(e-136) decoding: identical floats
  // And against the input: within the format's bound of the largest channel.
  for (size_t p = 0; p < ours.pixel_count(); ++p) {
    const float m = std::max({hdr_.rgb[3 * p], hdr_.rgb[3 * p + 1], hdr_.rgb[3 * p + 2]});
    for (int k = 0; k < 3; ++k) ASSERT_LE(std::abs(oiio.rgb[3 * p + size_t(k)] - hdr_.rgb[3 * p + size_t(k)]), 0x1p-8 * m);
  }
}

TEST_F(OiiotoolInterop, ExrHalfAndFloat) {
  const ImageRGB half = via_oiiotool(OutputFormat::kExrHalf, "h.exr");
  expect_close(half, read_exr(path("h.exr")), 0.0);
  const ImageRGB full = via_oiiotool(OutputFormat::kExrFloat, "f.exr");
  expect_close(full, hdr_, 0.0);
}

TEST_F(OiiotoolInterop, DdsRgb9e5WhenSupported) {
  ConvertOptions o;
  o.format = OutputFormat::kRgb9e5;
  convert_image(hdr_, path("t.dds"), o);
  if (!oiiotool_to_exr(path("t.dds"), path("t.dds.exr"))) {
    GTEST_SKIP() << "this oiiotool cannot read DX10 DDS (OIIO 2.4 lacks it); the DDS layout is "
                    "checked field by field in DdsRgb9e5.HeaderFollowsTheDx10LayoutAndTexelsRoundTrip";
  }
  int w = 0, h = 0;
  const auto tex = read_dds_rgb9e5(path("t.dds"), &w, &h);
  ImageRGB ours(w, h);
  for (size_t i = 0; i < tex.size(); ++i) {
    const Rgb c = decode_rgb9e5(tex[i]);
    for (int k = 0; k < 3; ++k) ours.rgb[3 * i + size_t(k)] = c[k];
  }
  expect_close(read_exr(path("t.dds.exr")), ours, 0.0, 1e-6);
}

}  // namespace
}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
#include "color/color_convert.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "color/bmp565.h"
#include "color/color_error.h"
#include "color/dds_rgb9e5.h"
#include "color/png_io.h"
#include "color/rgb9e5.h"
#include "color/rgbe.h"
#include "support/synthetic_images.h"
#include "image/exr_io.h"

namespace tessera::color {
namespace {

class ColorConvert : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("tessera_convert_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  std::filesystem::path dir_;
};

ConvertOptions opts(OutputFormat f, ToneMapOperator op = ToneMapOperator::kAces,
                    DitherMethod d = DitherMethod::kNone, int colors = 256) {
  ConvertOptions o;
  o.format = f;
  o.tonemap.op = op;
  o.dither = d;
  o.colors = colors;
  return o;
}

TEST_F(ColorConvert, EveryFormatWritesAFileAndReportsItsError) {
  const ImageRGB hdr = make_render_like(160, 120);
  struct Case {
    OutputFormat format;
    const char* file;
    int bpp;
    double min_psnr;
  };
  const Case cases[] = {{OutputFormat::kRgba8, "a.png", 32, 55.0},
                        {OutputFormat::kRgb8, "b.png", 24, 55.0},
                        {OutputFormat::kRgb565, "c.bmp", 16, 36.0},
                        {OutputFormat::kPalette, "d.png", 8, 38.0},
                        {OutputFormat::kRgbe, "e.hdr", 32, 45.0},
                        {OutputFormat::kRgb9e5, "f.dds", 32, 45.0},
                        {OutputFormat::kExrHalf, "g.exr", 48, 55.0},
                        {OutputFormat::kExrFloat, "h.exr", 96, 1e9}};
  for (const Case& c : cases) {
    const ConversionReport r = convert_image(hdr, path(c.file), opts(c.format));
    SCOPED_TRACE(report_text(r));
    EXPECT_EQ(r.bits_per_pixel, c.bpp);
    EXPECT_EQ(r.file_bytes, std::filesystem::file_size(path(c.file)));
    EXPECT_GT(r.file_bytes, 100u);
    EXPECT_GE(r.ldr.psnr_db, c.min_psnr);
    EXPECT_EQ(r.hdr.has_value(), is_hdr_format(c.format));
    EXPECT_GE(r.encode_seconds, 0.0);
  }
}

TEST_F(ColorConvert, ErrorReportsMatchTheFormatsGuarantees) {
  const ImageRGB hdr = make_render_like(160, 120);
  const auto rgb8 = convert_image(hdr, path("x.png"), opts(OutputFormat::kRgb8));
  EXPECT_LE(rgb8.ldr.max_abs, 0.5 + 1e-3);  // only rounding to 8 bits
  EXPECT_GT(rgb8.ldr.psnr_db, 58.0);        // uniform rounding error: ~58.9 dB
  const auto e = convert_image(hdr, path("x.hdr"), opts(OutputFormat::kRgbe));
  EXPECT_LE(e.hdr->max_rel, 0x1p-8);
  const auto e9 = convert_image(hdr, path("x.dds"), opts(OutputFormat::kRgb9e5));
  EXPECT_LE(e9.hdr->max_rel, 0x1p-9);
  const auto h = convert_image(hdr, path("x.exr"), opts(OutputFormat::kExrHalf));
  EXPECT_LE(h.hdr->max_rel, 0x1p-11);
  EXPECT_GT(h.hdr->mean_rel, 0.0);
  const auto f = convert_image(hdr, path("y.exr"), opts(OutputFormat::kExrFloat));
  EXPECT_EQ(f.hdr->max_rel, 0.0);
  EXPECT_TRUE(std::isinf(f.ldr.psnr_db));
}

TEST_F(ColorConvert, WrittenFilesHoldWhatTheReportMeasured) {
  ImageRGB hdr = make_render_like(40, 30);
  const auto r = convert_image(hdr, path("p.hdr"), opts(OutputFormat::kRgbe));
  int w = 0, h = 0;
  const auto px = read_radiance_hdr(path("p.hdr"), &w, &h);
  ASSERT_EQ(w, 40);
  for (size_t i = 0; i < px.size(); ++i) {
    ASSERT_EQ(px[i], encode_rgbe({hdr.rgb[3 * i], hdr.rgb[3 * i + 1], hdr.rgb[3 * i + 2]}));
  }
  convert_image(hdr, path("p.dds"), opts(OutputFormat::kRgb9e5));
  const auto tex = read_dds_rgb9e5(path("p.dds"), &w, &h);
  for (size_t i = 0; i < tex.size(); ++i) {
    ASSERT_EQ(tex[i], encode_rgb9e5({hdr.rgb[3 * i], hdr.rgb[3 * i + 1], hdr.rgb[3 * i + 2]}));
  }
  convert_image(hdr, path("p.exr"), opts(OutputFormat::kExrFloat));
  EXPECT_EQ(read_exr(path("p.exr")).rgb, hdr.rgb);
  EXPECT_GT(r.file_bytes, 0u);
}

TEST_F(ColorConvert, ExposureScalesHdrOutputs) {
  ImageRGB hdr(2, 1);
  hdr.rgb = {1.0f, 2.0f, 0.5f, 160.0f, 0.0f, 1e-3f};
  ConvertOptions o = opts(OutputFormat::kExrFloat);
  o.tonemap.exposure_ev = -1.0f;
  convert_image(hdr, path("e.exr"), o);
  const ImageRGB back = read_exr(path("e.exr"));
  EXPECT_EQ(back.rgb[0], 0.5f);
  EXPECT_EQ(back.rgb[3], 80.0f);
}

TEST_F(ColorConvert, NanInfAndNegativeInputsAreSanitizedInEveryFormat) {
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ImageRGB hdr(4, 2);
  hdr.rgb = {nan, nan, nan, inf, inf, inf, -inf, -1.0f, 0.5f, 1e38f, -0.0f, 0.25f,
             0.5f, 0.5f, 0.5f, nan, 1.0f, -inf, 1e-45f, 160.0f, 0.0f, 0.1f, 0.2f, 0.3f};
  for (OutputFormat f : {OutputFormat::kRgba8, OutputFormat::kRgb8, OutputFormat::kRgb565,
                         OutputFormat::kPalette, OutputFormat::kRgbe, OutputFormat::kRgb9e5,
                         OutputFormat::kExrHalf, OutputFormat::kExrFloat}) {
    for (auto op : {ToneMapOperator::kClamp, ToneMapOperator::kReinhard, ToneMapOperator::kAces,
                    ToneMapOperator::kPbrNeutral}) {
      const std::string p = path("s_" + std::string(format_name(f)) + ".out");
      const ConversionReport r = convert_image(hdr, p, opts(f, op));
      EXPECT_EQ(r.input.nan, 4u);
      EXPECT_EQ(r.input.pos_inf, 3u);
      EXPECT_EQ(r.input.neg_inf, 2u);
      EXPECT_EQ(r.input.negative, 1u);  // -0.0 is not negative
      EXPECT_FALSE(std::isnan(r.ldr.psnr_db));
      EXPECT_FALSE(std::isnan(r.ldr.max_abs));
      if (r.hdr) {
        EXPECT_FALSE(std::isnan(r.hdr->max_rel));
        EXPECT_FALSE(std::isnan(r.hdr->mean_rel));
      }
      EXPECT_NE(report_text(r).find("4 NaN"), std::string::npos);
      // Non-finite pixels are left out of the error; every finite value is in RGBE's range.
      if (f == OutputFormat::kRgbe) {
        EXPECT_LE(r.hdr->max_rel, 0x1p-8);
      }
    }
  }
  // The documented mapping, visible in the 8-bit file: NaN -> black, +Inf -> white (clamp).
  convert_image(hdr, path("s.png"), opts(OutputFormat::kRgb8, ToneMapOperator::kClamp));
  const Rgb8Image png = read_png_rgb8(path("s.png"));
  EXPECT_EQ(png.pixels[0], 0);
  EXPECT_EQ(png.pixels[3], 255);
  EXPECT_EQ(png.pixels[6], 0);  // -Inf -> 0
  // EXR keeps finite negatives and replaces NaN / Inf by 0 / the largest finite value.
  convert_image(hdr, path("s.exr"), opts(OutputFormat::kExrFloat));
  const ImageRGB exr = read_exr(path("s.exr"));
  EXPECT_EQ(exr.rgb[0], 0.0f);
  EXPECT_EQ(exr.rgb[3], std::numeric_limits<float>::max());
  EXPECT_EQ(exr.rgb[6], -std::numeric_limits<float>::max());
  EXPECT_EQ(exr.rgb[7], -1.0f);
}

TEST_F(ColorConvert, DitheringLowersBandingInEightBitAndPalette) {
  ImageRGB hdr(256, 32);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 256; ++x) {
      for (int c = 0; c < 3; ++c) hdr.at(x, y)[c] = 0.002f + 0.01f * float(x) / 255.0f;
    }
  }
  const auto plain = convert_image(hdr, path("g.png"), opts(OutputFormat::kRgb8, ToneMapOperator::kClamp));
  const auto blue = convert_image(hdr, path("gb.png"), opts(OutputFormat::kRgb8, ToneMapOperator::kClamp, DitherMethod::kBlueNoise));
  // Dithering adds noise (lower PSNR) ...
  EXPECT_LT(blue.ldr.psnr_db, plain.ldr.psnr_db);
  EXPECT_LE(blue.ldr.max_abs, 1.0);
  EXPECT_THROW(convert_image(hdr, path("bad.hdr"), opts(OutputFormat::kRgbe, ToneMapOperator::kClamp, DitherMethod::kBayer)), ColorError);
  EXPECT_THROW(convert_image(hdr, path("bad.png"), opts(OutputFormat::kPalette, ToneMapOperator::kClamp, DitherMethod::kBayer)), ColorError);
  EXPECT_THROW(convert_image(hdr, path("bad.bmp"), opts(OutputFormat::kRgb565, ToneMapOperator::kClamp, DitherMethod::kFloydSteinberg)), ColorError);
  EXPECT_THROW(convert_image(hdr, path("bad2.png"), opts(OutputFormat::kPalette, ToneMapOperator::kClamp, DitherMethod::kNone, 1)), ColorError);
}

TEST_F(ColorConvert, JsonReportIsMachineReadable) {
  const ImageRGB hdr = make_render_like(64, 48);
  ConvertOptions o = opts(OutputFormat::kPalette, ToneMapOperator::kReinhard, DitherMethod::kFloydSteinberg, 64);
  const auto r = convert_image(hdr, path("j.png"), o);
  const nlohmann::json j = nlohmann::json::parse(report_json(r).dump());
  EXPECT_EQ(j.at("format"), "palette");
  EXPECT_EQ(j.at("bits_per_pixel"), 8);
  EXPECT_LE(j.at("colors").get<int>(), 64);
  EXPECT_EQ(j.at("dither"), "floyd-steinberg");
  EXPECT_EQ(j.at("tonemap"), "reinhard");
  EXPECT_GT(j.at("white").get<double>(), 1.0);  // the brightest highlight sets it
  EXPECT_EQ(j.at("file_bytes").get<uint64_t>(), std::filesystem::file_size(path("j.png")));
  EXPECT_GT(j.at("psnr_db").get<double>(), 20.0);
  EXPECT_FALSE(j.contains("max_rel_error"));
  const auto f = convert_image(hdr, path("j.exr"), opts(OutputFormat::kExrFloat));
  const nlohmann::json jf = report_json(f);
  EXPECT_TRUE(jf.at("psnr_db").is_null());  // lossless: JSON has no infinity
  EXPECT_EQ(jf.at("max_rel_error").get<double>(), 0.0);
  // One line of text with the essentials.
  const std::string t = report_text(r);
  EXPECT_EQ(t.find('\n'), std::string::npos);
  EXPECT_NE(t.find("PSNR"), std::string::npos);
  EXPECT_NE(t.find("8 bpp"), std::string::npos);
}

TEST_F(ColorConvert, TinyImagesWorkInEveryFormat) {
  for (auto [w, h] : {std::pair{1, 1}, std::pair{1, 9}, std::pair{9, 1}}) {
    ImageRGB hdr = make_render_like(w, h);
    hdr.rgb[0] = 160.0f;
    for (OutputFormat f : {OutputFormat::kRgba8, OutputFormat::kRgb8, OutputFormat::kRgb565,
                           OutputFormat::kPalette, OutputFormat::kRgbe, OutputFormat::kRgb9e5,
                           OutputFormat::kExrHalf, OutputFormat::kExrFloat}) {
      for (DitherMethod d : {DitherMethod::kNone, DitherMethod::kFloydSteinberg}) {
        if (d == DitherMethod::kFloydSteinberg && f != OutputFormat::kPalette) continue;
        const auto r = convert_image(hdr, path("tiny.out"), opts(f, ToneMapOperator::kAces, d, 2));
        EXPECT_FALSE(std::isnan(r.ldr.psnr_db)) << format_name(f) << " " << w << "x" << h;
        EXPECT_GT(r.file_bytes, 0u);
      }
    }
  }
}

TEST(ColorConvertNames, FormatsAndExtensions) {
  for (const char* n : {"rgba8", "rgb8", "rgb565", "palette", "rgbe", "rgb9e5", "exr-half", "exr-float"}) {
    ASSERT_TRUE(parse_format(n).has_value()) << n;
    EXPECT_EQ(format_name(*parse_format(n)), n);
  }
  EXPECT_EQ(format_from_extension("a/b.PNG"), OutputFormat::kRgb8);
  EXPECT_EQ(format_from_extension("x.bmp"), OutputFormat::kRgb565);
  EXPECT_EQ(format_from_extension("x.hdr"), OutputFormat::kRgbe);
  EXPECT_EQ(format_from_extension("x.dds"), OutputFormat::kRgb9e5);
  EXPECT_EQ(format_from_extension("x.exr"), OutputFormat::kExrFloat);
  EXPECT_FALSE(format_from_extension("x.jpg").has_value());
}

}  // namespace
}  // namespace tessera::color

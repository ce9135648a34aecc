// SPDX-License-Identifier: Apache-2.0
#include "color/output_options.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "color/color_error.h"
#include "color/png_io.h"
#include "support/synthetic_images.h"

namespace tessera::color {
namespace {

// The flags that fill OutputOptions (--tonemap, --colors, ...) are the client's: their parsing
// and range checks are tested in client/output_flags_test.cpp.
TEST(OutputOptions, ResolvesEveryOption) {
  OutputOptions o;
  o.tonemap = "pbr-neutral";
  o.exposure_ev = -1.5f;
  o.white = 8.0f;
  o.format = "palette";
  o.colors = 64;
  o.dither = "floyd-steinberg";
  const ConvertOptions c = resolve_output_options(o, "x.png");
  EXPECT_EQ(c.format, OutputFormat::kPalette);
  EXPECT_EQ(c.tonemap.op, ToneMapOperator::kPbrNeutral);
  EXPECT_EQ(c.tonemap.exposure_ev, -1.5f);
  EXPECT_EQ(c.tonemap.white, 8.0f);
  EXPECT_EQ(c.dither, DitherMethod::kFloydSteinberg);
  EXPECT_EQ(c.colors, 64);
}

TEST(OutputOptions, UnknownNamesAreRefusedNamingTheFlag) {
  OutputOptions o;
  o.tonemap = "filmic";
  EXPECT_THROW(
      {
        try {
          resolve_output_options(o, "a.png");
        } catch (const ColorError& e) {
          EXPECT_STREQ(e.what(), "unknown --tonemap filmic");
          throw;
        }
      },
      ColorError);
  o.tonemap = "clamp";
  o.dither = "ordered";
  EXPECT_THROW(resolve_output_options(o, "a.png"), ColorError);
  o.dither = "none";
  o.format = "jpeg";
  EXPECT_THROW(resolve_output_options(o, "a.png"), ColorError);
}

TEST(OutputOptions, FormatComesFromTheExtensionUnlessGiven) {
  OutputOptions o;
  EXPECT_EQ(resolve_output_options(o, "a.png").format, OutputFormat::kRgb8);
  EXPECT_EQ(resolve_output_options(o, "a.bmp").format, OutputFormat::kRgb565);
  EXPECT_EQ(resolve_output_options(o, "a.hdr").format, OutputFormat::kRgbe);
  EXPECT_EQ(resolve_output_options(o, "a.dds").format, OutputFormat::kRgb9e5);
  EXPECT_EQ(resolve_output_options(o, "a.exr").format, OutputFormat::kExrFloat);
  EXPECT_THROW(resolve_output_options(o, "a.jpg"), ColorError);
  o.colors = 16;  // --colors on a .png: an indexed PNG
  EXPECT_EQ(resolve_output_options(o, "a.png").format, OutputFormat::kPalette);
  EXPECT_THROW(resolve_output_options(o, "a.bmp"), ColorError);
  o.colors = 0;
  o.format = "exr-half";
  EXPECT_EQ(resolve_output_options(o, "a.exr").format, OutputFormat::kExrHalf);
  o.format = "rgb8";
  o.dither = "floyd-steinberg";
  EXPECT_THROW(resolve_output_options(o, "a.png"), ColorError);
}

TEST(OutputOptions, WriteOutputPrintsOneReportLine) {
  const auto dir = std::filesystem::temp_directory_path() / "tessera_output_options";
  std::filesystem::create_directories(dir);
  OutputOptions o;
  o.tonemap = "aces";
  o.colors = 32;
  std::ostringstream text;
  const auto r = write_output(make_render_like(48, 32), (dir / "o.png").string(), o, text);
  EXPECT_EQ(r.format, OutputFormat::kPalette);
  EXPECT_LE(read_png_indexed((dir / "o.png").string()).palette.size(), 32u);
  const std::string line = text.str();
  EXPECT_EQ(std::count(line.begin(), line.end(), '\n'), 1);
  o.report = "json";
  std::ostringstream json;
  write_output(make_render_like(48, 32), (dir / "o.png").string(), o, json);
  EXPECT_EQ(nlohmann::json::parse(json.str()).at("colors").get<int>(), r.palette_colors);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace tessera::color

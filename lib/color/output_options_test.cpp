#include "color/output_options.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>

#include "color/color_error.h"
#include "color/png_io.h"
#include "support/synthetic_images.h"

namespace tessera::color {
namespace {

// Parses a command line for a subcommand carrying the output options, as `tessera render`
// would after add_output_options.
OutputOptions parse(std::vector<std::string> args) {
  CLI::App app;
  OutputOptions o;
  CLI::App* sub = app.add_subcommand("render");
  add_output_options(*sub, o);
  args.insert(args.begin(), "render");
  std::reverse(args.begin(), args.end());  // CLI11 takes a reversed vector
  app.parse(args);
  return o;
}

TEST(OutputOptions, ParsesEveryOption) {
  const OutputOptions o = parse({"--tonemap", "pbr-neutral", "--exposure", "-1.5", "--white", "8",
                                 "--format", "palette", "--colors", "64", "--dither",
                                 "floyd-steinberg", "--report", "json"});
  EXPECT_EQ(o.tonemap, "pbr-neutral");
  EXPECT_EQ(o.exposure_ev, -1.5f);
  EXPECT_EQ(o.white, 8.0f);
  EXPECT_EQ(o.colors, 64);
  const ConvertOptions c = resolve_output_options(o, "x.png");
  EXPECT_EQ(c.format, OutputFormat::kPalette);
  EXPECT_EQ(c.tonemap.op, ToneMapOperator::kPbrNeutral);
  EXPECT_EQ(c.dither, DitherMethod::kFloydSteinberg);
  EXPECT_EQ(c.colors, 64);
}

TEST(OutputOptions, RejectsBadValuesAtParseTime) {
  EXPECT_THROW(parse({"--tonemap", "filmic"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--colors", "1"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--colors", "257"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--format", "jpeg"}), CLI::ValidationError);
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

// SPDX-License-Identifier: Apache-2.0
#include "output_flags.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace tessera::cli {
namespace {

// Parses a command line for a subcommand carrying the output options, as `tessera render` does.
color::OutputOptions parse(std::vector<std::string> args) {
  CLI::App app;
  color::OutputOptions o;
  CLI::App* sub = app.add_subcommand("render");
  add_output_options(*sub, o);
  args.insert(args.begin(), "render");
  std::reverse(args.begin(), args.end());  // CLI11 takes a reversed vector
  app.parse(args);
  return o;
}

TEST(OutputFlags, ParsesEveryOption) {
  const color::OutputOptions o = parse({"--tonemap", "pbr-neutral", "--exposure", "-1.5", "--white", "8",
                                        "--format", "palette", "--colors", "64", "--dither", "floyd-steinberg",
                                        "--report", "json"});
  EXPECT_EQ(o.tonemap, "pbr-neutral");
  EXPECT_EQ(o.exposure_ev, -1.5f);
  EXPECT_EQ(o.white, 8.0f);
  EXPECT_EQ(o.format, "palette");
  EXPECT_EQ(o.colors, 64);
  EXPECT_EQ(o.dither, "floyd-steinberg");
  EXPECT_EQ(o.report, "json");
  const color::ConvertOptions c = color::resolve_output_options(o, "x.png");
  EXPECT_EQ(c.format, color::OutputFormat::kPalette);
  EXPECT_EQ(c.colors, 64);
}

TEST(OutputFlags, DefaultsAreTheStructs) {
  const color::OutputOptions o = parse({});
  EXPECT_EQ(o.tonemap, "clamp");
  EXPECT_EQ(o.exposure_ev, 0.0f);
  EXPECT_EQ(o.white, 0.0f);
  EXPECT_EQ(o.format, "");
  EXPECT_EQ(o.colors, 0);
  EXPECT_EQ(o.dither, "none");
  EXPECT_EQ(o.report, "text");
}

TEST(OutputFlags, HelpShowsTheDefaults) {
  CLI::App app;
  color::OutputOptions o;
  add_output_options(app, o);
  EXPECT_EQ(app.get_option("--tonemap")->get_default_str(), "clamp");
  EXPECT_EQ(app.get_option("--exposure")->get_default_str(), "0");
  EXPECT_EQ(app.get_option("--dither")->get_default_str(), "none");
  EXPECT_EQ(app.get_option("--report")->get_default_str(), "text");
}

TEST(OutputFlags, RejectsBadValuesAtParseTime) {
  EXPECT_THROW(parse({"--tonemap", "filmic"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--colors", "1"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--colors", "257"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--format", "jpeg"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--dither", "ordered"}), CLI::ValidationError);
  EXPECT_THROW(parse({"--report", "xml"}), CLI::ValidationError);
  EXPECT_NO_THROW(parse({"--colors", "2"}));
  EXPECT_NO_THROW(parse({"--colors", "256"}));
}

TEST(OutputFlags, ARefusalNamesTheFlagAndWhatItTakes) {
  try {
    parse({"--colors", "1"});
    FAIL() << "--colors 1 was accepted";
  } catch (const CLI::ValidationError& e) {
    EXPECT_EQ(std::string(e.what()), "--colors: Value 1 not in range 2 to 256");
  }
  try {
    parse({"--tonemap", "filmic"});
    FAIL() << "--tonemap filmic was accepted";
  } catch (const CLI::ValidationError& e) {
    EXPECT_EQ(std::string(e.what()), "--tonemap: filmic not in {clamp,reinhard,aces,pbr-neutral}");
  }
}

}  // namespace
}  // namespace tessera::cli

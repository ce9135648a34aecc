// SPDX-License-Identifier: Apache-2.0
// `tessera render` as a user runs it: the real binary, real files, an independent EXR reader.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "image/exr_io.h"

namespace {

namespace fs = std::filesystem;

struct CmdResult {
  int status;
  std::string output;
};

CmdResult run(const std::string& cmd) {
  CmdResult r{0, {}};
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return {-1, "popen failed"};
  std::array<char, 4096> buf;
  while (fgets(buf.data(), int(buf.size()), p)) r.output += buf.data();
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

const std::string kTessera = std::string(TESSERA_BINARY_DIR) + "/client/tessera";
const std::string kScenes = std::string(TESSERA_SOURCE_DIR) + "/scenes";

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(RenderCli, RendersTheShowcaseToAFloatExrThatOiiotoolReads) {
  const std::string out = (dir_ / "frames/whitted_####.exr").string();
  const CmdResult r = run(kTessera + " render " + kScenes + "/whitted.json -o " + out +
                    " --width 96 --height 54 --spp 4 --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const fs::path file = dir_ / "frames/whitted_0000.exr";
  ASSERT_TRUE(fs::exists(file)) << r.output;
  // The one-line summary: time, Mrays/s, estimated RMSE.
  EXPECT_NE(r.output.find("Mrays/s"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("est. RMSE"), std::string::npos) << r.output;
  tessera::ExrAttributes attrs;
  const tessera::ImageRGB img = tessera::read_exr(file.string(), &attrs);
  EXPECT_EQ(img.width, 96);
  EXPECT_EQ(img.height, 54);
  EXPECT_EQ(std::get<int64_t>(attrs.at("tessera:spp")), 4);
  EXPECT_GT(std::stoll(std::get<std::string>(attrs.at("tessera:raysTraced"))), 96 * 54 * 4);

  if (run("command -v oiiotool").status != 0) GTEST_SKIP() << "oiiotool not installed";
  const CmdResult info = run("oiiotool --info -v " + file.string());
  ASSERT_EQ(info.status, 0) << info.output;
  EXPECT_NE(info.output.find("96 x   54, 3 channel, float"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("tessera:spp: 4"), std::string::npos) << info.output;
}

// --exr-compression: the file is compressed as asked (exrheader, an independent reader, says so)
// and holds the same pixels; a lossy or unknown codec is refused, naming the allowed ones.
TEST_F(RenderCli, ExrCompressionIsTheOneAskedForAndLossless) {
  const std::string base = kTessera + " render " + kScenes + "/whitted.json --width 64 --height 48 --spp 2 --quiet -o ";
  std::map<std::string, std::vector<float>> pixels;
  for (const std::string c : {"zip", "piz", "none"}) {
    const fs::path file = dir_ / (c + ".exr");
    const CmdResult r = run(base + file.string() + (c == "zip" ? "" : " --exr-compression " + c));
    ASSERT_EQ(r.status, 0) << r.output;
    pixels[c] = tessera::read_exr(file.string()).rgb;
    if (run("command -v exrheader").status != 0) continue;
    const CmdResult h = run("exrheader " + file.string());
    EXPECT_NE(h.output.find("compression (type compression): " + std::string(c == "none" ? "none" : c)),
              std::string::npos) << h.output;
  }
  EXPECT_EQ(pixels["piz"], pixels["zip"]);
  EXPECT_EQ(pixels["none"], pixels["zip"]);
  const CmdResult bad = run(base + (dir_ / "bad.exr").string() + " --exr-compression dwaa");
  EXPECT_EQ(bad.status, 2) << "bad input\n" << bad.output;
  EXPECT_NE(bad.output.find("--exr-compression"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("piz"), std::string::npos) << "the allowed values are named\n" << bad.output;
  EXPECT_FALSE(fs::exists(dir_ / "bad.exr"));
}

// A bad command line is bad input: exit 2 (docs/farm.md), with CLI11's message naming the option;
// asking for help is not an error.
TEST_F(RenderCli, ABadCommandLineExitsTwoAndHelpZero) {
  const std::string render = kTessera + " render " + kScenes + "/whitted.json -o " + (dir_ / "x.exr").string();
  const std::pair<std::string, std::string> cases[] = {
      {" --spp abc", "--spp"}, {" --tonemap sepia", "--tonemap"}, {" --bogus", "--bogus"}};
  for (const auto& [args, named] : cases) {
    const CmdResult r = run(render + args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(named), std::string::npos) << r.output;
  }
  EXPECT_EQ(run(kTessera + " render").status, 2);  // the scene is required
  EXPECT_EQ(run(kTessera + " render --help").status, 0);
  EXPECT_FALSE(fs::exists(dir_ / "x.exr"));
}

// The README's picture (docs/whitted.png) is what the first command leaves, not an older render:
// the showcase at its own size and spp, tone-mapped as scripts/showcase.sh does. idiff, an
// independent reader, allows what another machine's kernels may change (a few edge pixels by a
// step or two), not a different scene, size, tone map or exposure.
TEST_F(RenderCli, TheReadmePictureIsTheShowcaseAsRenderedToday) {
  const std::string out = (dir_ / "whitted.png").string();
  const CmdResult r = run(kTessera + " render " + kScenes + "/whitted.json -o " + out + " --tonemap aces --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const CmdResult diff = run("idiff -warn 0.02 -warnpercent 0.5 -fail 0.02 -failpercent 0.5 " + out + " " + std::string(TESSERA_SOURCE_DIR) +
                             "/docs/whitted.png");
  EXPECT_EQ(diff.status, 0) << "docs/whitted.png differs from today's showcase: render it again with\n  "
                            << "tessera render scenes/whitted.json -o docs/whitted.png --tonemap aces\n" << diff.output;
}

TEST_F(RenderCli, TheSameFrameIsBitIdenticalAcrossTileSizesAndThreadCounts) {
  const std::string base = kTessera + " render " + kScenes + "/cornell.json --width 40 --height 40 --spp 3 -q";
  ASSERT_EQ(run(base + " -o " + (dir_ / "a.exr").string() + " --tile 7 --threads 1").status, 0);
  ASSERT_EQ(run(base + " -o " + (dir_ / "b.exr").string() + " --tile 64 --threads 2").status, 0);
  EXPECT_EQ(tessera::read_exr((dir_ / "a.exr").string()).rgb, tessera::read_exr((dir_ / "b.exr").string()).rgb);
}

TEST_F(RenderCli, BadInputFailsWithAMessageNamingTheProblem) {
  std::ofstream(dir_ / "bad.json") << R"({"camera": {"position": [0,0,5], "look_at": [0,0,0]},
    "materials": {"m": {"type": "diffuse"}},
    "objects": [{"type": "sphere", "center": [0,0,0], "radius": -2, "material": "m"}]})";
  CmdResult r = run(kTessera + " render " + (dir_ / "bad.json").string() + " -o " + (dir_ / "x.exr").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("bad.json: objects[0].radius: must be in (0,"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "x.exr"));

  r = run(kTessera + " render " + (dir_ / "nope.json").string() + " -o " + (dir_ / "x.exr").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("nope.json: scene file not found"), std::string::npos) << r.output;

  r = run(kTessera + " render " + kScenes + "/whitted.json --spp 0 -o " + (dir_ / "x.exr").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("--spp: must be in [1, 65536], got 0"), std::string::npos) << r.output;

  r = run(kTessera + " render " + kScenes + "/whitted.json --width 8 --height 8 -q -o /proc/nope/x.exr");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("/proc/nope/x.exr"), std::string::npos) << r.output;
}

TEST_F(RenderCli, TargetErrorRenderReportsItsErrorAndSamplesAndWritesErrorLayers) {
  const fs::path file = dir_ / "adaptive.exr";
  const std::string base = kTessera + " render " + kScenes + "/cornell.json --width 48 --height 48 -q ";
  CmdResult r = run(base + "--target-rmse 0.02 --min-spp 8 --max-spp 1024 --error-channels --report json -o " +
                    file.string());
  ASSERT_EQ(r.status, 0) << r.output;
  const auto json_start = r.output.find('{');
  ASSERT_NE(json_start, std::string::npos) << r.output;
  const auto report = nlohmann::json::parse(r.output.substr(json_start));
  const double est = report.at("estimated_rmse").get<double>();
  EXPECT_GT(est, 0.0);
  EXPECT_LE(est, 0.02);
  EXPECT_EQ(report.at("target_rmse").get<double>(), 0.02);
  EXPECT_EQ(report.at("spp_min").get<int>(), 8);
  EXPECT_GT(report.at("spp_max").get<int>(), 8);
  EXPECT_TRUE(report.at("target_reached").get<bool>());
  const double mean_spp = report.at("spp_mean").get<double>();

  // The layers, through the library's reader and through an independent one (oiiotool).
  tessera::ExrAttributes attrs;
  tessera::read_exr(file.string(), &attrs);
  EXPECT_EQ(std::get<double>(attrs.at("tessera:estimatedRmse")), est);
  EXPECT_EQ(std::get<double>(attrs.at("tessera:targetRmse")), 0.02);
  const std::vector<float> err = tessera::read_exr_channel(file.string(), "error.Y");
  const std::vector<float> spp = tessera::read_exr_channel(file.string(), "spp.Y");
  ASSERT_EQ(err.size(), 48u * 48u);
  double mse = 0, spp_sum = 0;
  for (size_t i = 0; i < err.size(); ++i) {
    mse += double(err[i]) * double(err[i]) / double(err.size());
    spp_sum += spp[i] / double(spp.size());
  }
  EXPECT_NEAR(std::sqrt(mse), est, 1e-6 * est);  // the layer is the per-pixel form of the estimate
  EXPECT_NEAR(spp_sum, mean_spp, 1e-9 * mean_spp);
  if (run("command -v oiiotool").status == 0) {
    const CmdResult info = run("oiiotool --info -v " + file.string());
    ASSERT_EQ(info.status, 0) << info.output;
    EXPECT_NE(info.output.find("5 channel"), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("error.Y"), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("spp.Y"), std::string::npos) << info.output;
    const CmdResult stats = run("oiiotool " + file.string() + " --ch spp.Y --printstats");
    EXPECT_NE(stats.output.find("Min: 8.000000"), std::string::npos) << stats.output;
  }

  // max_spp too low for the target: done, exit 0, with a warning that says so.
  r = run(base + "--target-rmse 0.0005 --max-spp 16 -o " + (dir_ / "capped.exr").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("target RMSE 0.0005 not reached: frame estimated RMSE"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--max-spp 16"), std::string::npos) << r.output;

  // The block bound: every block's own estimate, with its own name in the report and the file.
  r = run(base + "--block-rmse 0.02 --report json -o " + (dir_ / "block.exr").string());
  ASSERT_EQ(r.status, 0) << r.output;
  const auto block = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(block.at("block_rmse").get<double>(), 0.02);
  EXPECT_EQ(block.at("min_spp").get<int>(), 16);  // the block bound's default
  EXPECT_FALSE(block.contains("target_rmse"));
  attrs.clear();
  tessera::read_exr((dir_ / "block.exr").string(), &attrs);
  EXPECT_EQ(std::get<double>(attrs.at("tessera:blockRmse")), 0.02);
  r = run(base + "--block-rmse 0.0005 --max-spp 16 -o " + (dir_ / "capped.exr").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("block RMSE 0.0005 not reached everywhere"), std::string::npos) << r.output;
}

TEST_F(RenderCli, BadTargetErrorSettingsNameTheFlagAndTheAllowedValues) {
  const std::string base = kTessera + " render " + kScenes + "/whitted.json --width 8 --height 8 -q -o " +
                           (dir_ / "x.exr").string() + " ";
  const std::pair<std::string, std::string> cases[] = {
      {"--target-rmse 0", "--target-rmse: must be a finite number > 0"},
      {"--target-rmse -0.1", "--target-rmse: must be a finite number > 0"},
      {"--target-rmse nan", "--target-rmse: must be a finite number > 0"},
      {"--target-rmse inf", "--target-rmse: must be a finite number > 0"},
      {"--target-rmse 0.01 --min-spp 64 --max-spp 32", "--min-spp (64) must not exceed --max-spp (32)"},
      {"--target-rmse 0.01 --spp 64", "--spp and --target-rmse conflict"},
      {"--max-spp 64", "--max-spp bounds a render to a target error: give --target-rmse or --block-rmse too"},
      {"--block-rmse 0", "--block-rmse: must be a finite number > 0"},
      {"--target-rmse 0.01 --block-rmse 0.01", "--target-rmse and --block-rmse conflict"},
      {"--block-rmse 0.01 --spp 8", "--spp and --block-rmse conflict"},
      {"--block-rmse 0.01 --sampler center", "--block-rmse needs a progressive sampler"},
      {"--min-spp 2048 --target-rmse 0.01", "--min-spp (2048) must not exceed --max-spp (1024)"},
      {"--target-rmse 0.01 --sampler cmj", "--target-rmse needs a progressive sampler"},
      {"--target-rmse 0.01 --max-spp 100000", "--max-spp: must be in [2, 65536], got 100000"},
      {"--sampler sobel", "--sampler: must be one of sobol, stratified, cmj, independent, center"},
  };
  for (const auto& [args, message] : cases) {
    const CmdResult r = run(base + args);
    EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "x.exr")) << args;
  }
}

TEST_F(RenderCli, ASceneReadingOutsideItsFolderRendersWithAWarning) {
  // An OBJ whose mtllib lies outside the scene's folder: `tessera render` follows it (it is the
  // user's own machine) but says that the farm cannot bundle it.
  fs::create_directories(dir_ / "elsewhere");
  fs::create_directories(dir_ / "scene");
  std::ofstream(dir_ / "elsewhere/m.mtl") << "newmtl red\nKd 0.8 0.1 0.1\n";
  std::ofstream(dir_ / "scene/tri.obj") << "mtllib ../elsewhere/m.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
  std::ofstream(dir_ / "scene/s.json") << R"({"camera": {"position": [0,0,4], "look_at": [0,0,0]},
    "lights": [{"type": "point", "position": [0, 0, 3], "intensity": 10}],
    "materials": {"m": {"type": "diffuse"}},
    "objects": [{"type": "mesh", "file": "tri.obj", "material": "m"}]})";
  const CmdResult r = run(kTessera + " render " + (dir_ / "scene/s.json").string() + " --width 8 --height 8 -q -o " +
                          (dir_ / "x.exr").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("outside the scene's folder"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("m.mtl"), std::string::npos) << r.output;
}

TEST_F(RenderCli, EveryEdgeCaseMeshRendersOrFailsCleanly) {
  // No crash on any file that breaks naive loaders: exit status 0 or 2, never a signal.
  const fs::path cases = fs::path(TESSERA_SOURCE_DIR) / "tests/data/obj-edge-cases";
  for (const auto& e : fs::directory_iterator(cases)) {
    if (e.path().extension() != ".obj") continue;
    SCOPED_TRACE(e.path().filename().string());
    std::ofstream(dir_ / "mesh.json") << R"({"camera": {"position": [3, 4, 8], "look_at": [0, 0, 0]},
      "image": {"width": 16, "height": 16, "spp": 1},
      "lights": [{"type": "point", "position": [2, 5, 5], "intensity": 50}],
      "objects": [{"type": "mesh", "file": ")" + e.path().string() + R"("}]})";
    const CmdResult r = run(kTessera + " render " + (dir_ / "mesh.json").string() + " -q -o " + (dir_ / "m.exr").string());
    EXPECT_TRUE(r.status == 0 || r.status == 2) << r.status << ": " << r.output;
    if (r.status == 2) {
      EXPECT_NE(r.output.find(e.path().filename().string()), std::string::npos) << r.output;
    }
  }
}

}  // namespace

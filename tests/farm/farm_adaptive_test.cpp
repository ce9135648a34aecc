// Block-bound jobs on the farm (--block-rmse, the farm's adaptive mode): the frames are
// bit-identical to `tessera render` with the same settings, whatever the tile size, the number of
// workers and the tiles rendered again after a worker died; the client previews frames as they
// converge and reports the error it reached. A frame target (--target-rmse) is refused, naming
// what to do instead.
#include <gtest/gtest.h>
#include <signal.h>

#include <nlohmann/json.hpp>
#include <fstream>
#include <thread>

#include "farm_harness.h"
#include "image/exr_io.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");
const std::vector<std::string> kTarget = {"--block-rmse", "0.01", "--min-spp", "8", "--max-spp", "128"};

// The first preview of a frame in progress that can be read whole, or an empty path on timeout.
fs::path wait_for_preview(const fs::path& dir, ExrAttributes* attrs, std::chrono::seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (e.path().string().find(".preview.exr") == std::string::npos) continue;
      try {
        read_exr(e.path().string(), attrs);
        return e.path();
      } catch (const ExrError&) {
        // removed between listing and reading: the frame was just written; look again
      }
    }
    std::this_thread::sleep_for(10ms);
  }
  return {};
}

TEST(FarmAdaptive, TargetErrorJobIsBitIdenticalToRenderThroughAWorkerDeath) {
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "3000", "--heartbeat-ms", "300"});
  Process& victim = farm.start_worker("victim", 1, 40);
  farm.start_worker("survivor", 1, 40);
  const fs::path out = farm.dir() / "out";
  fs::create_directories(out);
  // 12-pixel tiles: the 8x8 blocks the sampler decides on straddle tiles, and are rendered by
  // both neighbours; the result must not show it.
  std::vector<std::string> args{"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                                (out / "frame_####.exr").string(), "--tile", "12", "--frames", "0-1",
                                "--error-channels", "--preview-every", "0.1"};
  args.insert(args.end(), kTarget.begin(), kTarget.end());
  auto client = farm.cli_async(args, "submit.log");
  const std::string job = wait_job_id(*client);
  ASSERT_FALSE(job.empty()) << client->log();

  // A frame can be looked at before it is done.
  ExrAttributes preview;
  const fs::path p = wait_for_preview(out, &preview, 60s);
  ASSERT_FALSE(p.empty()) << client->log();
  EXPECT_LT(std::get<int64_t>(preview.at("tessera:tilesDone")), std::get<int64_t>(preview.at("tessera:tilesTotal")));

  ASSERT_TRUE(farm.wait_tiles_done(job, 20));
  std::string state;
  ASSERT_LT(farm.tiles_done(job, &state), 2 * 48) << "job finished before the worker could be killed";
  victim.signal(SIGKILL);
  ASSERT_EQ(client->wait(120s), 0) << client->log() << farm.server().log();

  const std::string log = client->log();
  EXPECT_NE(log.find("block RMSE 0.01 (spp 8-128)"), std::string::npos) << log;  // the job line
  EXPECT_NE(log.find("(block bound 0.01), spp 8-"), std::string::npos) << log;    // each frame's result
  std::vector<std::string> ref_args = kTarget;
  ref_args.push_back("--error-channels");
  for (int f = 0; f < 2; ++f) {
    const fs::path got = out / ("frame_000" + std::to_string(f) + ".exr");
    const fs::path ref = reference_frame(kScene, f, ref_args);
    EXPECT_EQ(compare_exr(got, ref), "") << "frame " << f;
    EXPECT_EQ(read_exr_channel(got.string(), "spp.Y"), read_exr_channel(ref.string(), "spp.Y")) << "frame " << f;
    EXPECT_EQ(read_exr_channel(got.string(), "error.Y"), read_exr_channel(ref.string(), "error.Y")) << "frame " << f;
    ExrAttributes a, b;
    read_exr(got.string(), &a);
    read_exr(ref.string(), &b);
    EXPECT_EQ(std::get<double>(a.at("tessera:estimatedRmse")), std::get<double>(b.at("tessera:estimatedRmse")));
    EXPECT_EQ(std::get<double>(a.at("tessera:sppMean")), std::get<double>(b.at("tessera:sppMean")));
    EXPECT_FALSE(fs::exists(out / ("frame_000" + std::to_string(f) + ".preview.exr"))) << "preview left behind";
  }
  CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  EXPECT_EQ(nlohmann::json::parse(st.output).at("block_rmse").get<double>(), 0.01);
}

TEST(FarmAdaptive, TargetFromTheSceneFileReachesTheWorkersAndWatch) {
  // The target written in the scene file, not on the command line: the coordinator resolves it
  // into the job's settings, so `tessera watch` (which has no scene) reports against it.
  Farm farm;
  farm.start_server();
  farm.start_worker("w1");
  std::string text = read_text(kScene);
  const std::string from = R"("spp": 4,)";
  text.replace(text.find(from), from.size(), R"("block_rmse": 0.02, "min_spp": 8, "max_spp": 64,)");
  const fs::path scene = farm.dir() / "target.json";
  { std::ofstream(scene) << text; }
  CliResult sub = farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--frames", "0", "--detach"});
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string()});
  ASSERT_EQ(w.code, 0) << w.output << farm.server().log();
  EXPECT_NE(w.output.find("(block bound 0.02), spp 8-"), std::string::npos) << w.output;
  EXPECT_EQ(compare_exr(out / "f_0000.exr", reference_frame(scene, 0, {})), "");
}

TEST(FarmAdaptive, AFrameTargetIsRefusedWithWhatToDoInstead) {
  // A frame target's samples depend on the whole frame (render/frame_target.h); a farm of
  // independent tiles cannot render it the same as `tessera render`, so it takes no such job,
  // from the command line or from the scene file, rather than render something else.
  Farm farm;
  farm.start_server();
  CliResult sub = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--frames", "0", "--detach",
                            "--target-rmse", "0.01"});
  EXPECT_NE(sub.code, 0) << sub.output;
  EXPECT_NE(sub.output.find("target_rmse 0.01"), std::string::npos) << sub.output;
  EXPECT_NE(sub.output.find("--block-rmse"), std::string::npos) << sub.output;
  EXPECT_NE(sub.output.find("tessera render --target-rmse"), std::string::npos) << sub.output;
  std::string text = read_text(kScene);
  const std::string from = R"("spp": 4,)";
  text.replace(text.find(from), from.size(), R"("target_rmse": 0.02,)");
  const fs::path scene = farm.dir() / "target.json";
  { std::ofstream(scene) << text; }
  sub = farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--frames", "0", "--detach"});
  EXPECT_NE(sub.code, 0) << sub.output;
  EXPECT_NE(sub.output.find("--block-rmse"), std::string::npos) << sub.output;
  CliResult list = farm.cli({"status", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(list.code, 0) << list.output;
  EXPECT_EQ(list.output.find("target"), std::string::npos) << "a refused job was kept: " << list.output;
}

}  // namespace
}  // namespace tessera::farmtest

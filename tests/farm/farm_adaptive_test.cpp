// SPDX-License-Identifier: Apache-2.0
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

// The farm's frames out/PREFIX0000.exr ... are those of `tessera render ARGS --error-channels`, bit
// for bit, their error and sample-count layers included.
void expect_frames_like_render(const fs::path& out, const std::string& prefix, int frames,
                               std::vector<std::string> args) {
  args.push_back("--error-channels");
  for (int f = 0; f < frames; ++f) {
    const fs::path got = out / (prefix + "000" + std::to_string(f) + ".exr");
    const fs::path ref = reference_frame(kScene, f, args);
    EXPECT_EQ(compare_exr(got, ref), "") << "frame " << f;
    EXPECT_EQ(read_exr_channel(got.string(), "spp.Y"), read_exr_channel(ref.string(), "spp.Y")) << "frame " << f;
    EXPECT_EQ(read_exr_channel(got.string(), "error.Y"), read_exr_channel(ref.string(), "error.Y")) << "frame " << f;
  }
}

TEST(FarmAdaptive, TargetErrorJobIsBitIdenticalToRenderThroughAWorkerDeath) {
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "3000", "--heartbeat-ms", "300"});
  // The victim alone, slow enough (96 tiles at 100 ms) that it cannot finish the job before it is
  // killed however loaded the machine; the survivor joins once it is dead.
  Process& victim = farm.start_worker("victim", 1, 100);
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
  farm.start_worker("survivor", 1, 0);
  ASSERT_EQ(client->wait(120s), 0) << client->log() << farm.server().log();

  const std::string log = client->log();
  EXPECT_NE(log.find("block RMSE 0.01 (spp 8-128)"), std::string::npos) << log;  // the job line
  EXPECT_NE(log.find("(block bound 0.01), spp 8-"), std::string::npos) << log;    // each frame's result
  expect_frames_like_render(out, "frame_", 2, kTarget);
  std::vector<std::string> ref_args = kTarget;
  ref_args.push_back("--error-channels");
  for (int f = 0; f < 2; ++f) {
    const fs::path got = out / ("frame_000" + std::to_string(f) + ".exr");
    const fs::path ref = reference_frame(kScene, f, ref_args);
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

// The lattice sampler renders in-process only: a farm job asking for it is refused at submit,
// naming it, rather than rendered with another sampler into a frame `tessera render` would not
// make.
TEST(FarmAdaptive, TheLatticeSamplerIsRefusedAtSubmitByName) {
  Farm farm;
  farm.start_server();
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--target-rmse",
                          "0.02", "--sampler", "lattice"});
  EXPECT_NE(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("sampler lattice: renders in-process only"), std::string::npos) << r.output;
  CliResult list = farm.cli({"status", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(list.code, 0) << list.output;
  EXPECT_EQ(nlohmann::json::parse(list.output).size(), 0u) << list.output;
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

TEST(FarmAdaptive, AFrameTargetJobIsBitIdenticalToRenderThroughAWorkerDeath) {
  // --target-rmse on the farm: a pilot pass, then passes planned at the coordinator from the
  // statistics the workers report (sampling/pass_plan.h), tiles of 11 pixels so that the 2x2
  // allocation blocks straddle tiles, a worker killed mid-job. The frames, their per-pixel error and sample counts
  // are the bits `tessera render --target-rmse` makes.
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "3000", "--heartbeat-ms", "300"});
  Process& victim = farm.start_worker("victim", 1, 100);  // alone and slow: see above
  const fs::path out = farm.dir() / "out";
  fs::create_directories(out);
  const std::vector<std::string> target = {"--target-rmse", "0.006", "--min-spp", "8", "--max-spp", "256"};
  std::vector<std::string> args{"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                                (out / "frame_####.exr").string(), "--tile", "11", "--frames", "0-1",
                                "--error-channels"};
  args.insert(args.end(), target.begin(), target.end());
  auto client = farm.cli_async(args, "submit.log");
  const std::string job = wait_job_id(*client);
  ASSERT_FALSE(job.empty()) << client->log();
  ASSERT_TRUE(farm.wait_tiles_done(job, 20));
  std::string state;
  farm.tiles_done(job, &state);
  ASSERT_NE(state, "done") << "job finished before the worker could be killed";
  victim.signal(SIGKILL);
  farm.start_worker("survivor", 1, 0);
  ASSERT_EQ(client->wait(180s), 0) << client->log() << farm.server().log();
  const std::string log = client->log();
  EXPECT_NE(log.find("target RMSE 0.006 (spp 8-256)"), std::string::npos) << log;
  expect_frames_like_render(out, "frame_", 2, target);
  for (int f = 0; f < 2; ++f) {
    const fs::path got = out / ("frame_000" + std::to_string(f) + ".exr");
    const std::vector<float> spp = read_exr_channel(got.string(), "spp.Y");
    ASSERT_FALSE(spp.empty());
    EXPECT_GT(*std::max_element(spp.begin(), spp.end()), 8.0f) << "no pass after the pilot: the test tests nothing";
    ExrAttributes a;
    read_exr(got.string(), &a);
    EXPECT_EQ(std::get<double>(a.at("tessera:targetRmse")), 0.006);
    EXPECT_LE(std::get<double>(a.at("tessera:estimatedRmse")), 0.006);
  }
}

TEST(FarmAdaptive, AWorkerWithoutBlockStatisticsIsRefusedNotPlannedFrom) {
  // A frame-target tile without its statistics (a worker that renders them the old way) cannot
  // be planned from: the coordinator refuses each such result as a fault of its worker, and with
  // no other worker the job fails, saying why, rather than write a frame planned from nothing.
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "3000", "--heartbeat-ms", "300"});
  farm.start_worker("old", 1, 0, {"--test-fault", "no-block-stats"});
  const fs::path out = farm.dir() / "out";
  CliResult sub = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--frames", "0", "-o",
                            (out / "f_####.exr").string(), "--target-rmse", "0.01"});
  EXPECT_NE(sub.code, 0) << sub.output;
  EXPECT_NE(sub.output.find("failed"), std::string::npos) << sub.output;
  // A 32x32 tile starts 16 x 16 allocation blocks of 2x2 pixels.
  EXPECT_NE(sub.output.find("tile carries 0 block statistics, expected 256 (frame targets need them)"),
            std::string::npos)
      << sub.output;
  EXPECT_FALSE(fs::exists(out / "f_0000.exr"));
}

TEST(FarmAdaptive, AFrameTargetJobSurvivesACoordinatorKilledMidPass) {
  // kill -9 of the coordinator while frames are between passes: the frames stored are final, the
  // others start again from their pilot (their passes live in the coordinator's memory only), and
  // every frame comes out as `tessera render` makes it.
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "3000", "--heartbeat-ms", "300"});
  farm.start_worker("w1", 1, 30);
  const std::vector<std::string> target = {"--target-rmse", "0.006", "--min-spp", "8", "--max-spp", "256"};
  std::vector<std::string> args{"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16",
                                "--frames", "0-2", "--detach"};
  args.insert(args.end(), target.begin(), target.end());
  CliResult sub = farm.cli(args);
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 30));  // frame 0 final, frame 1 in its passes
  std::string state;
  farm.tiles_done(job, &state);
  ASSERT_NE(state, "done") << "the job ended before the coordinator could be killed";
  farm.restart_server();
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string(),
                          "--error-channels"});
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  expect_frames_like_render(out, "f_", 3, target);
}

}  // namespace
}  // namespace tessera::farmtest

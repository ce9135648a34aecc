// SPDX-License-Identifier: Apache-2.0
// End-to-end farm tests: a real coordinator, real workers and the real CLI on 127.0.0.1.
// Images are small (96x64, 4 spp, 16 px tiles: 24 tiles a frame) so the suite stays fast on two
// cores; workers that must be killed mid-job are slowed with --test-delay-ms.
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <nlohmann/json.hpp>
#include <fstream>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");
constexpr int kFrames = 3;

void expect_frames_identical(const fs::path& dir) {
  for (int f = 0; f < kFrames; ++f) {
    const fs::path got = dir / ("frame_000" + std::to_string(f) + ".exr");
    EXPECT_EQ(compare_exr(got, reference_frame(kScene, f, {})), "") << "frame " << f;
  }
}

// Also: the client writes its frames with the compression asked for (PIZ here; zip by default),
// losslessly.
TEST(FarmEndToEnd, ThreeFramesTwoWorkersBitIdenticalToRender) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1");
  farm.start_worker("w2");
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (out / "frame_####.exr").string(), "--tile", "16", "--exr-compression", "piz"});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  EXPECT_NE(r.output.find("est. RMSE"), std::string::npos) << r.output;
  expect_frames_identical(out);
  for (int f = 0; f < kFrames; ++f) {
    const fs::path frame = out / ("frame_000" + std::to_string(f) + ".exr");
    EXPECT_EQ(Imf::InputFile(frame.c_str()).header().compression(), Imf::PIZ_COMPRESSION) << frame;
  }
  // Both workers took part, and the coordinator has every tile exactly once.
  const std::string job = job_id_from(r.output);
  std::string state;
  EXPECT_EQ(farm.tiles_done(job, &state), kFrames * 24);
  EXPECT_EQ(state, "done");
  CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(w.code, 0) << w.output;
  auto workers = nlohmann::json::parse(w.output);
  ASSERT_EQ(workers.size(), 2u);
  int total = 0;
  for (const auto& x : workers) total += x.at("tiles_done").get<int>();
  EXPECT_EQ(total, kFrames * 24);
}

// Frames in a color format: tone-mapped PNGs byte-identical to `tessera render` to the same
// format, each written beside its name and renamed into place, and reported under its own name
// (not the temporary one it was written to).
TEST(FarmEndToEnd, PngFramesMatchRenderAndAreReportedUnderTheirNames) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1", 2);
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (out / "frame_####.png").string(), "--tile", "16", "--tonemap", "aces", "--frames", "1"});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  EXPECT_NE(r.output.find("rgb8 " + (out / "frame_0001.png").string() + " 96x64"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find(".tmp"), std::string::npos) << r.output;
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(out)) files.push_back(e.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"frame_0001.png"});
  const fs::path ref = farm.dir() / "ref.png";
  const CliResult rr = farm.cli({"render", kScene.string(), "--frame", "1", "-o", ref.string(), "--tonemap", "aces", "-q"});
  ASSERT_EQ(rr.code, 0) << rr.output;
  EXPECT_EQ(read_text(out / "frame_0001.png"), read_text(ref)) << "the farm's PNG differs from tessera render's";
}

TEST(FarmEndToEnd, WorkerKilledMidJobJobStillCompletesIdentical) {
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "3000", "--heartbeat-ms", "300"});
  // The victim alone, slow enough that it cannot finish the job before it is killed however loaded
  // the machine; the survivor joins once it is dead.
  Process& victim = farm.start_worker("victim", 1, 100);
  const fs::path out = farm.dir() / "out";
  auto client = farm.cli_async({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                                (out / "frame_####.exr").string(), "--tile", "16"},
                               "submit.log");
  const std::string job = wait_job_id(*client);
  ASSERT_FALSE(job.empty()) << client->log();
  ASSERT_TRUE(farm.wait_tiles_done(job, 12));
  std::string state;
  ASSERT_LT(farm.tiles_done(job, &state), kFrames * 24) << "job finished before the worker could be killed";
  victim.signal(SIGKILL);
  farm.start_worker("survivor", 1, 0);
  ASSERT_EQ(client->wait(120s), 0) << client->log() << farm.server().log();
  expect_frames_identical(out);
  EXPECT_EQ(farm.tiles_done(job, &state), kFrames * 24);
  EXPECT_NE(farm.server().log().find("'victim' left"), std::string::npos);
}

TEST(FarmEndToEnd, ClientKilledThenWatchWritesCompleteFrames) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1", 1, 30);
  farm.start_worker("w2", 1, 30);
  const fs::path out = farm.dir() / "out";
  const std::string pattern = (out / "frame_####.exr").string();
  auto client = farm.cli_async({"submit", kScene.string(), "--coordinator", farm.address(), "-o", pattern, "--tile",
                                "16"},
                               "submit.log");
  const std::string job = wait_job_id(*client);
  ASSERT_FALSE(job.empty()) << client->log();
  ASSERT_TRUE(farm.wait_tiles_done(job, 30));  // frame 0 finished, frame 1 under way
  client->signal(SIGKILL);
  client->wait(10s);
  CliResult r = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", pattern});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  expect_frames_identical(out);
}

TEST(FarmEndToEnd, WorkerJoiningAfterStartGetsWork) {
  Farm farm;
  farm.start_server();
  farm.start_worker("early", 1, 40);
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 4));
  farm.start_worker("late", 1, 0);
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  expect_frames_identical(out);
  CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(w.code, 0) << w.output;
  int late_tiles = -1;
  for (const auto& x : nlohmann::json::parse(w.output)) {
    if (x.at("name") == "late") late_tiles = x.at("tiles_done").get<int>();
  }
  EXPECT_GT(late_tiles, 0) << w.output;
}

// A worker sends a heartbeat only after an interval without any other message (busy workers send
// none: their results are their sign of life). One with nothing to do must still send them: idle
// for three and a half lease timeouts, it stays the one session it was, and then renders.
TEST(FarmEndToEnd, AnIdleWorkerKeepsItsSessionThroughManyLeaseTimeouts) {
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "2000", "--heartbeat-ms", "200"});
  farm.start_worker("quiet", 1, 0);
  std::this_thread::sleep_for(std::chrono::seconds(7));
  const std::string log = farm.server().log();
  EXPECT_EQ(log.find("missed heartbeats"), std::string::npos) << log;
  size_t joins = 0;
  for (size_t at = log.find("'quiet' joined"); at != std::string::npos; at = log.find("'quiet' joined", at + 1)) ++joins;
  EXPECT_EQ(joins, 1u) << "the worker was dropped and reconnected\n" << log;
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "-o",
                          (out / "frame_####.exr").string()});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  expect_frames_identical(out);
}

TEST(FarmEndToEnd, CancelStopsTheJob) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1", 1, 50);
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 2));
  CliResult c = farm.cli({"cancel", job, "--coordinator", farm.address()});
  ASSERT_EQ(c.code, 0) << c.output;
  EXPECT_NE(c.output.find("cancelled"), std::string::npos) << c.output;
  std::string state;
  const int done = farm.tiles_done(job, &state);
  EXPECT_EQ(state, "cancelled");
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(farm.tiles_done(job), done);  // nothing more was handed out
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address()});
  EXPECT_EQ(w.code, 3) << w.output;
}

TEST(FarmErrors, UnreachableCoordinatorNamesAddressAndRemedy) {
  Farm farm;
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", "127.0.0.1:1", "-o",
                          (farm.dir() / "x.exr").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("cannot reach the coordinator at 127.0.0.1:1"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("tessera-server --listen"), std::string::npos) << r.output;
}

TEST(FarmErrors, InvalidSceneUnknownJobUnwritableOutput) {
  Farm farm;
  farm.start_server();
  const fs::path bad = farm.dir() / "bad.json";
  {
    std::ofstream f(bad);
    f << R"({"objects": [{"type": "sphere", "radius": -1}]})";
  }
  CliResult r = farm.cli({"submit", bad.string(), "--coordinator", farm.address(), "-o",
                          (farm.dir() / "x.exr").string()});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("bad.json"), std::string::npos) << r.output;

  r = farm.cli({"status", "nosuchjob", "--coordinator", farm.address()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("no job 'nosuchjob'"), std::string::npos) << r.output;
  r = farm.cli({"watch", "nosuchjob", "--coordinator", farm.address()});
  EXPECT_EQ(r.code, 2);
  r = farm.cli({"cancel", "nosuchjob", "--coordinator", farm.address()});
  EXPECT_EQ(r.code, 2);

  r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o", "/proc/tessera/x_####.exr"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("not writable"), std::string::npos) << r.output;
}

// A bad command line is bad input for every program: exit 2 and a message naming the flag, not
// CLI11's own codes (105 for a value out of range); --help exits 0.
TEST(FarmErrors, BadFlagsExitTwoNamingTheFlagInEveryProgram) {
  Farm farm;
  struct Case {
    std::vector<std::string> argv;
    std::string named;
  };
  const Case cases[] = {{{bin("tessera-server").string(), "--heartbeat-ms", "soon"}, "--heartbeat-ms"},
                        {{bin("tessera-server").string(), "--no-such-flag"}, "--no-such-flag"},
                        {{bin("tessera-worker").string(), "--threads", "-3"}, "--threads"},
                        {{bin("tessera").string(), "submit", kScene.string(), "--tile", "9999"}, "--tile"}};
  int n = 0;
  for (const Case& c : cases) {
    Process p(c.argv, farm.dir() / ("flags" + std::to_string(n++) + ".log"));
    EXPECT_EQ(p.wait(20s), 2) << c.argv[0] << " " << c.named << "\n" << p.log();
    EXPECT_NE(p.log().find(c.named), std::string::npos) << p.log();
  }
  Process help({bin("tessera-worker").string(), "--help"}, farm.dir() / "help.log");
  EXPECT_EQ(help.wait(20s), 0) << help.log();
}

TEST(FarmPython, IndependentPythonClientListsWorkersAndSubmits) {
  if (!fs::exists("/usr/bin/python3")) GTEST_SKIP() << "/usr/bin/python3 not installed";
  Farm farm;
  farm.start_server();
  farm.start_worker("py-w1");
  // Wait until the worker has registered, so the script sees it.
  for (int i = 0; i < 200; ++i) {
    CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
    if (w.code == 0 && nlohmann::json::parse(w.output).size() == 1) break;
    std::this_thread::sleep_for(50ms);
  }
  Process py({"/usr/bin/python3", source("tests/farm/python_client.py").string(), farm.address(),
              source("proto").string(), kScene.string(), farm.dir().string()},
             farm.dir() / "python.log");
  const int rc = py.wait(120s);
  EXPECT_EQ(rc, 0) << py.log() << farm.server().log();
  EXPECT_NE(py.log().find("py-w1"), std::string::npos) << py.log();
}

}  // namespace
}  // namespace tessera::farmtest

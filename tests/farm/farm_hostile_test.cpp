// SPDX-License-Identifier: Apache-2.0
// What a hostile or broken peer must not achieve, with real processes on loopback: a wrong frame
// written with exit status 0 (a watcher handed a tile between passes; a result relabelled to its
// lease), a job stalled by sessions that take tiles and never render them, unbounded strings in
// the log, the database or every client's status, resident tiles held by cancelled jobs, and
// absurd statistics reaching the job's sums. docs/reliability.md ("What a hostile peer can cost")
// lists each promise beside its test here.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");   // 3 frames, 96x64
const fs::path kLong = source("tests/farm/chaos_orbit.json");      // 10 frames
const std::vector<std::string> kTarget = {"--target-rmse", "0.012"};

// Every frame `pattern` names (f_####.exr in `dir`) that exists is bit-identical to `tessera
// render` with `args`; returns how many exist.
int expect_written_frames_like_render(const fs::path& scene, const fs::path& dir, int frames,
                                      const std::vector<std::string>& args) {
  int written = 0;
  for (int f = 0; f < frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "f_%04d.exr", f);
    if (!fs::exists(dir / name)) continue;
    ++written;
    EXPECT_EQ(compare_exr(dir / name, reference_frame(scene, f, args)), "") << (dir / name);
  }
  return written;
}

void wait_for_workers(Farm& farm, size_t n) {
  for (int i = 0; i < 200; ++i) {
    CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
    if (w.code == 0 && nlohmann::json::parse(w.output).size() >= n) return;
    std::this_thread::sleep_for(50ms);
  }
}

// Two liars (worker name -> --test-fault mode) beside an honest worker on the 3-frame scene: the
// job completes with every frame bit-identical to `tessera render`, whatever the liars sent.
// Returns the job id ("" after a failed assertion).
std::string render_beside_liars(Farm& farm, const std::vector<std::pair<std::string, std::string>>& liars) {
  farm.start_server({"--max-faults", "3"});
  for (const auto& [name, mode] : liars) farm.start_worker(name, 1, 0, {"--test-fault", mode});
  farm.start_worker("good", 1, 20);
  wait_for_workers(farm, liars.size() + 1);
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (out / "f_####.exr").string(), "--tile", "16"});
  EXPECT_EQ(r.code, 0) << r.output << farm.server_logs();
  if (r.code != 0) return {};
  EXPECT_EQ(expect_written_frames_like_render(kScene, out, 3, {}), 3);
  return job_id_from(r.output);
}

// A watcher attaching while a frame-target job runs gets a frame's tiles only once its last pass
// ended: every frame it writes is the frame `tessera render --target-rmse` makes.
TEST(FarmHostile, AWatcherAttachingMidPassWritesOnlyFinalFrames) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1", 1, 60);
  farm.start_worker("w2", 1, 60);
  std::vector<std::string> args{"submit", kLong.string(), "--coordinator", farm.address(), "--frames", "0-5",
                                "--tile", "16", "--detach"};
  args.insert(args.end(), kTarget.begin(), kTarget.end());
  CliResult sub = farm.cli(args);
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 30));  // some frames final, one in its passes
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string(),
                          "--error-channels"},
                         300s);
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  EXPECT_EQ(expect_written_frames_like_render(kLong, out, 6, kTarget), 6);
}

// Seeded, reproducible interleavings of what can happen to a frame-target job: watchers
// attaching and being killed, the coordinator killed -9 and restarted, workers dying and joining
// (speculative copies). Every frame any watcher wrote is the frame `tessera render` makes, and
// together they are every frame. TESSERA_INTERLEAVING_SEEDS=N runs N seeds (default 2 in CI).
TEST(FarmHostile, RandomInterleavingsOfAttachKillRestartAndSpeculationWriteOnlyRightFrames) {
  const char* env = std::getenv("TESSERA_INTERLEAVING_SEEDS");
  const int seeds = env ? std::max(1, std::atoi(env)) : 2;
  for (int seed = 1; seed <= seeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng{uint32_t(seed)};
    Farm farm;
    farm.start_server({"--lease-timeout-ms", "2000", "--heartbeat-ms", "200"});
    int workers = 0;
    const auto add_worker = [&] {
      farm.start_worker("w" + std::to_string(++workers), 1, 20 + int(rng() % 40));
    };
    add_worker();
    add_worker();
    std::vector<std::string> args{"submit", kLong.string(), "--coordinator", farm.address(), "--frames", "0-4",
                                  "--tile", "16", "--detach"};
    args.insert(args.end(), kTarget.begin(), kTarget.end());
    CliResult sub = farm.cli(args);
    ASSERT_EQ(sub.code, 0) << sub.output;
    const std::string job = job_id_from(sub.output);
    std::unique_ptr<Process> watcher;
    std::vector<fs::path> dirs;
    for (int event = 0; event < 6; ++event) {
      std::this_thread::sleep_for(std::chrono::milliseconds(300 + rng() % 900));
      std::string state;
      farm.tiles_done(job, &state);
      if (state == "done") break;
      switch (rng() % 4) {
        case 0:  // a watcher attaches (the previous one, if any, is killed first: one place at a time)
          if (watcher) watcher->signal(SIGKILL), watcher->wait(10s);
          dirs.push_back(farm.dir() / ("out" + std::to_string(dirs.size())));
          watcher = farm.cli_async({"watch", job, "--coordinator", farm.address(), "-o",
                                    (dirs.back() / "f_####.exr").string()},
                                   "watch" + std::to_string(dirs.size()) + ".log");
          break;
        case 1:
          farm.restart_server(std::chrono::milliseconds(rng() % 300));
          break;
        case 2:  // a worker dies (its leases expire) and another joins
          farm.workers()[rng() % farm.workers().size()]->signal(SIGKILL);
          add_worker();
          break;
        default:  // one more worker: idle ones take speculative copies of tiles in flight
          add_worker();
          break;
      }
    }
    if (watcher) {
      const int code = watcher->wait(300s);
      EXPECT_TRUE(code == 0 || code == 128 + SIGKILL) << code << watcher->log();
    }
    dirs.push_back(farm.dir() / "final");
    CliResult last = farm.cli({"watch", job, "--coordinator", farm.address(), "-o",
                               (dirs.back() / "f_####.exr").string()},
                              300s);
    ASSERT_EQ(last.code, 0) << last.output << farm.server_logs();
    int written = 0;
    for (const fs::path& d : dirs) written += expect_written_frames_like_render(kLong, d, 5, kTarget);
    EXPECT_GE(written, 5) << "every frame was written by some watcher";
    if (HasFailure()) return;
  }
}

// A result must be for exactly the job, frame and tile its lease names: one that names another
// frame (with that frame's pixels) or another job is refused as a fault, never relabelled; the
// honest worker's frames are right.
TEST(FarmHostile, AResultNamingAnotherFrameOrJobThanItsLeaseIsRefused) {
  Farm farm;
  const std::string job = render_beside_liars(farm, {{"liar-frame", "other-frame"}, {"liar-job", "other-job"}});
  ASSERT_FALSE(job.empty());
  const std::string log = farm.server_logs();
  EXPECT_NE(log.find("the result names job '" + job + "' frame "), std::string::npos) << log;
  EXPECT_NE(log.find("the result names job '0123456789ab'"), std::string::npos) << log;
  for (const char* liar : {"'liar-frame'", "'liar-job'"}) {
    EXPECT_NE(log.find(std::string(liar) + " is blocklisted for job " + job), std::string::npos) << liar << log;
  }
}

// Sessions that heartbeat and take tiles but never render cannot stall a job: they hold no more
// than their credit, and lose what they hold once they have returned nothing for the stall
// timeout; the honest worker renders every tile.
TEST(FarmHostile, SessionsThatNeverRenderCannotStallAJob) {
  Farm farm;
  farm.start_server({"--stall-timeout-ms", "2000"});
  farm.start_worker("hoarder-1", 16, 0, {"--test-fault", "idle"});
  farm.start_worker("hoarder-2", 16, 0, {"--test-fault", "idle"});
  wait_for_workers(farm, 2);
  CliResult sub = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--frames", "0",
                            "--tile", "16", "--detach"});  // 24 tiles
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  std::this_thread::sleep_for(500ms);  // the hoarders take what they can
  farm.start_worker("honest", 1, 0);
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string()},
                         120s);
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  EXPECT_EQ(expect_written_frames_like_render(kScene, out, 1, {}), 1);
  EXPECT_NE(farm.server_logs().find("returned nothing for longer than the stall limit"), std::string::npos);
}

// A worker's failure reason of 20 MB is stored, logged and shown bounded: the job it fails
// still answers `tessera status` for every client, also after a restart, and the log stays small.
TEST(FarmHostile, AHugeFailureReasonIsBoundedEverywhere) {
  Farm farm;
  farm.start_server({"--max-faults", "2"});
  farm.start_worker("verbose", 1, 0, {"--test-fault", "long-reason"});
  wait_for_workers(farm, 1);
  CliResult sub = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--frames", "0",
                            "--detach"});
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  std::string state;
  for (int i = 0; i < 200 && state != "failed"; ++i) {
    farm.tiles_done(job, &state);
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(state, "failed") << farm.server_logs();
  // Cancelling an ended job answers once everything before it is stored: the failure is durable
  // before the kill -9 below (which would otherwise lose the last commit window).
  ASSERT_EQ(farm.cli({"cancel", job, "--coordinator", farm.address()}).code, 0);
  for (int start = 0; start < 2; ++start) {
    CliResult st = farm.cli({"status", "--coordinator", farm.address()});
    ASSERT_EQ(st.code, 0) << st.output.substr(0, 2000);
    CliResult one = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
    ASSERT_EQ(one.code, 0) << one.output.substr(0, 2000);
    const std::string error = nlohmann::json::parse(one.output).at("error");
    EXPECT_LT(error.size(), 4096u);
    EXPECT_NE(error.find("(20971520 bytes)"), std::string::npos) << error.substr(0, 500);
    farm.restart_server();
  }
  EXPECT_LT(farm.server_logs().size(), size_t(1) << 20) << "the log grew with the reasons";
}

// Results for jobs that do not exist are faults of their session, and a flood of them (one
// message of 5,000, with 4 KiB job ids: a Python worker session) costs the log a few lines with
// bounded ids, and one more saying how many were left out.
TEST(FarmHostile, ResultsForUnknownJobsAreLoggedWithARateLimitAndBoundedIds) {
  Farm farm;
  farm.start_server();
  Process py({"/usr/bin/python3", source("tests/farm/security_probe.py").string(), farm.address(),
              source("proto").string(), farm.dir().string(), "stray-results"},
             farm.dir() / "probe.log");
  ASSERT_EQ(py.wait(120s), 0) << py.log();
  std::string log;
  for (int i = 0; i < 100; ++i) {  // the summary comes when the session has ended
    log = farm.server_logs();
    if (log.find("more such warnings about worker") != std::string::npos) break;
    std::this_thread::sleep_for(50ms);
  }
  size_t lines = 0;
  for (size_t at = 0; (at = log.find("refused a result for unknown job", at)) != std::string::npos; ++at) ++lines;
  size_t left_out = 0;
  const std::regex summary(R"((\d+) more such warnings about worker)");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), summary); it != std::sregex_iterator(); ++it) {
    left_out += std::stoul((*it)[1]);
  }
  EXPECT_GE(lines, 1u) << log.substr(0, 4000);
  EXPECT_LE(lines, 10u) << "one line a second, not one per result";
  EXPECT_EQ(lines + left_out, 5000u) << "every refused result is logged or counted as left out";
  EXPECT_EQ(log.find(std::string(200, 'j')), std::string::npos) << "a 4 KiB job id went into the log whole";
  EXPECT_LT(log.size(), size_t(256) << 10);
}

// A cancelled job gives the tiles of its started, unfinished frames back to --max-resident-tiles
// at once: another client's job fits right after, also after a restart.
TEST(FarmHostile, ACancelledJobReleasesItsResidentTilesAtOnce) {
  Farm farm;
  // whitted_orbit: frames of 96x64 in 8-px tiles = 96 tiles; the limit holds one started frame.
  farm.start_server({"--max-resident-tiles", "150"});
  const auto submit = [&] {
    return farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "8", "--detach"});
  };
  CliResult first = submit();
  ASSERT_EQ(first.code, 0) << first.output;
  // A slow worker starts the first frame (its table is built with its first lease), then dies
  // holding its leases: the frame stays in memory, unfinished.
  Process& slow = farm.start_worker("slow", 1, 60000);
  ASSERT_TRUE(poll_until(30s, [&] {
    CliResult st = farm.cli({"status", job_id_from(first.output), "--json", "--coordinator", farm.address()});
    return st.code == 0 && nlohmann::json::parse(st.output).value("tiles_resident", 0) == 96;
  })) << farm.server_logs();
  slow.signal(SIGKILL);
  CliResult refused = submit();
  ASSERT_NE(refused.code, 0) << "the limit does not hold two jobs: the test tests nothing";
  ASSERT_NE(refused.output.find("--max-resident-tiles"), std::string::npos) << refused.output;
  ASSERT_EQ(farm.cli({"cancel", job_id_from(first.output), "--coordinator", farm.address()}).code, 0);
  CliResult second = submit();
  ASSERT_EQ(second.code, 0) << second.output;
  ASSERT_EQ(farm.cli({"cancel", job_id_from(second.output), "--coordinator", farm.address()}).code, 0);
  farm.restart_server();
  CliResult third = submit();
  EXPECT_EQ(third.code, 0) << third.output;
  CliResult st = farm.cli({"status", job_id_from(first.output), "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  EXPECT_EQ(nlohmann::json::parse(st.output).at("state"), "cancelled");
}

// Finite but absurd statistics (a render longer than its lease has existed, more samples a pixel
// than the job allows) are faults: they never reach the job's sums or the work-seconds gauge.
TEST(FarmHostile, AbsurdStatisticsAreRefusedAndNeverCounted) {
  Farm farm;
  ASSERT_FALSE(render_beside_liars(farm, {{"slow-clock", "absurd-seconds"}, {"many-samples", "absurd-spp"}}).empty());
  const std::string log = farm.server_logs();
  EXPECT_NE(log.find("render time 1e+300 s is longer than its lease has existed"), std::string::npos) << log;
  EXPECT_NE(log.find("a pixel took 4294967295 samples, more than the job's 4"), std::string::npos) << log;
  CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(w.code, 0) << w.output;
  for (const auto& x : nlohmann::json::parse(w.output)) {
    EXPECT_LT(x.at("render_seconds").get<double>(), 3600.0) << x.dump();
    if (x.at("name") != "good") {
      EXPECT_GE(x.at("results_refused").get<int64_t>(), 3) << x.dump();
    }
  }
}

// An error never echoes a peer's string unbounded: a 1 MiB job id gets INVALID_ARGUMENT naming
// the field and its bound, not a transport error about oversized metadata (a Python client: a
// command line cannot carry 1 MiB).
TEST(FarmHostile, AnOversizedJobIdIsRefusedNamingTheFieldNotEchoed) {
  Farm farm;
  farm.start_server();
  Process py({"/usr/bin/python3", source("tests/farm/security_probe.py").string(), farm.address(),
              source("proto").string(), farm.dir().string(), "huge-job-id"},
             farm.dir() / "probe.log");
  EXPECT_EQ(py.wait(120s), 0) << py.log();
}

}  // namespace
}  // namespace tessera::farmtest

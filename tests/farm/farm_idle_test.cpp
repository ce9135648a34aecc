// SPDX-License-Identifier: Apache-2.0
// tessera-worker --exit-when-idle: a worker that leaves by itself once the farm has nothing for it
// (a Slurm allocation or a Kubernetes Job then ends with the queue), and never while it has work.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 96x64, 3 frames

size_t workers_listed(Farm& farm) {
  CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
  return w.code == 0 ? nlohmann::json::parse(w.output).size() : size_t(-1);
}

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// With nothing to render, the worker leaves after its idle time (not before, not much after) with
// status 0, and the coordinator lists it no more at once: it left, it did not go silent.
TEST(FarmIdle, AnIdleWorkerLeavesAtItsTimeWithStatusZero) {
  Farm farm;
  farm.start_server();
  const auto started = Clock::now();
  Process& w = farm.start_worker("idle", 1, 0, {"--exit-when-idle", "2"});
  for (int i = 0; i < 100 && workers_listed(farm) != 1; ++i) std::this_thread::sleep_for(20ms);
  ASSERT_EQ(workers_listed(farm), 1u) << w.log();
  const int rc = w.wait(20s);
  const double after = seconds_since(started);
  EXPECT_EQ(rc, 0) << w.log();
  EXPECT_GE(after, 2.0) << "left before its idle time";
  EXPECT_LT(after, 6.0) << "left long after its idle time";
  EXPECT_NE(w.log().find("--exit-when-idle"), std::string::npos) << w.log();
  EXPECT_EQ(workers_listed(farm), 0u) << "the coordinator still lists the worker that left";
}

// A job of slow tiles (0.3 s each, 18 of them: over 5 s) on a worker whose idle time is 1 s: it
// never leaves while it has tiles, renders every one of them (the frames are those of `tessera
// render`), and leaves about a second after the queue emptied.
TEST(FarmIdle, AWorkerWithWorkStaysAndLeavesWhenTheQueueEmpties) {
  Farm farm;
  farm.start_server();
  // The job first, so the worker has tiles from its first second.
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "32", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  Process& w = farm.start_worker("busy", 1, 300, {"--exit-when-idle", "1"});
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"watch", job_id_from(s.output), "--coordinator", farm.address(), "-o",
                          (out / "frame_####.exr").string()});
  const auto done = Clock::now();
  // Read at once: the worker may rightly leave a second after the job, and the reference frames
  // below take longer than that on a loaded machine (they had made this test fail there).
  const std::string log_at_done = w.log();
  ASSERT_EQ(r.code, 0) << r.output << log_at_done;
  EXPECT_EQ(log_at_done.find("--exit-when-idle"), std::string::npos) << "it left while the job ran:\n" << log_at_done;
  EXPECT_EQ(w.wait(10s), 0) << w.log();
  EXPECT_LT(seconds_since(done), 4.0);
  EXPECT_NE(w.log().find("--exit-when-idle"), std::string::npos) << w.log();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }
}

// Idle counts while the coordinator is away too: a worker whose coordinator never comes back
// does not hold its allocation forever.
TEST(FarmIdle, AWorkerWithoutACoordinatorLeavesAtItsTimeToo) {
  Farm farm;
  farm.start_server();
  Process& w = farm.start_worker("orphan", 1, 0, {"--exit-when-idle", "2"});
  for (int i = 0; i < 100 && workers_listed(farm) != 1; ++i) std::this_thread::sleep_for(20ms);
  farm.stop_server();
  EXPECT_EQ(w.wait(20s), 0) << w.log();
  EXPECT_NE(w.log().find("--exit-when-idle"), std::string::npos) << w.log();
}

// What a worker holds when it leaves goes back at once: the leave of --exit-when-idle is the
// leave of SIGTERM (WorkerConnection::request_stop), and an idle worker can only hold a tile that
// arrived as it decided to go. So here the leave has a tile in hand for certain: a one-thread
// worker with slow tiles (1.5 s) holds one running and one unstarted when it is told to go. The
// unstarted one is returned and the running one finished; a second worker then renders the rest,
// and the job ends long before the 60 s lease timeout, with no lease expired.
TEST(FarmIdle, WhatALeavingWorkerHeldIsRequeuedAtOnce) {
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "60000"});
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "32", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  Process& slow = farm.start_worker("slow", 1, 1500, {"--exit-when-idle", "30"});
  int in_flight = 0;
  for (int i = 0; i < 200 && in_flight < 2; ++i) {
    CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
    if (w.code == 0) {
      for (const auto& x : nlohmann::json::parse(w.output)) in_flight = x.at("tiles_in_flight").get<int>();
    }
    std::this_thread::sleep_for(25ms);
  }
  ASSERT_EQ(in_flight, 2) << "the worker did not take its two tiles";
  const auto told = Clock::now();
  slow.signal(SIGTERM);
  EXPECT_EQ(slow.wait(20s), 0) << slow.log();
  EXPECT_NE(slow.log().find("returned 1 unstarted tiles"), std::string::npos) << slow.log();
  farm.start_worker("fast");
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()}, 50s);
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }
  EXPECT_LT(seconds_since(told), 40.0) << "a tile waited for its lease to expire";
  EXPECT_EQ(farm.server().log().find("expired"), std::string::npos) << farm.server().log();
}

}  // namespace
}  // namespace tessera::farmtest

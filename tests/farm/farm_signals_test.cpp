// SPDX-License-Identifier: Apache-2.0
// Stop signals with real processes: SIGINT and SIGTERM are taken by the one thread that waits for
// them (farm/stop_signals.h), so a stop is always the clean one. A thread that does not block them
// (gRPC starts its executor and timer threads as soon as credentials are made) lets the kernel
// end the process by the default action instead (CI once saw a coordinator's clean stop end as a
// kill by SIGTERM, exit 143, which loses the commit window's tiles).
#include <gtest/gtest.h>
#include <signal.h>

#include <regex>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

std::string names(const std::vector<std::string>& threads) {
  std::string s;
  for (const auto& t : threads) s += "\n  " + t;
  return s;
}

// Samples the process's threads a few times: never more than one may take `sig`, and one must
// (a waiter that steps out of its wait for an instant, as the worker's does, is sampled again).
void expect_one_thread_takes(const Process& p, int sig) {
  bool seen_one = false;
  for (int i = 0; i < 20; ++i) {
    const std::vector<std::string> taking = threads_taking(p.pid(), sig);
    ASSERT_LE(taking.size(), 1u) << "signal " << sig << " can be taken by these threads:" << names(taking);
    seen_one = seen_one || taking.size() == 1;
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_TRUE(seen_one) << "no thread waits for signal " << sig;
}

TEST(FarmSignals, OnlyTheWaitingThreadsTakeStopSignalsAndSigtermStopsCleanly) {
  Farm farm;
  farm.start_server();
  Process& worker = farm.start_worker("w1", 2);
  // Let the worker join, so that every gRPC thread of both processes has started.
  CliResult r = farm.cli({"workers", "--coordinator", farm.address()});
  for (int i = 0; i < 100 && r.output.find("w1") == std::string::npos; ++i) {
    std::this_thread::sleep_for(50ms);
    r = farm.cli({"workers", "--coordinator", farm.address()});
  }
  ASSERT_NE(r.output.find("w1"), std::string::npos) << r.output << farm.server_logs();
  for (int sig : {SIGTERM, SIGINT}) {
    SCOPED_TRACE("signal " + std::to_string(sig));
    expect_one_thread_takes(farm.server(), sig);
    expect_one_thread_takes(worker, sig);
  }
  // The main thread is the coordinator's waiter: SIGTERM stops it, exit 0, saying so.
  EXPECT_EQ(threads_taking(farm.server().pid(), SIGTERM).at(0).rfind(std::to_string(farm.server().pid()) + " ", 0), 0u);
  farm.server().signal(SIGTERM);
  EXPECT_EQ(farm.server().wait(30s), 0) << farm.server().log();
  EXPECT_NE(farm.server().log().find("shutting down"), std::string::npos) << farm.server().log();
  worker.signal(SIGTERM);
  EXPECT_EQ(worker.wait(30s), 0) << worker.log();
}

// Ctrl-C on an attached `tessera submit` (client/interrupt.h): the job is the farm's and keeps
// rendering; the client ends by SIGINT right away, says how to come back or cancel, and leaves
// only whole files; `tessera watch` then writes the other frames, bit-identical.
TEST(FarmSignals, CtrlCOnAnAttachedSubmitLeavesTheJobRenderingAndSaysHowToComeBack) {
  const fs::path scene = source("tests/farm/whitted_orbit.json");  // 96x64, 3 frames
  Farm farm;
  farm.start_server();
  farm.start_worker("w1", 1, 60);  // 60 ms a tile: 24 tiles a frame, about 1.5 s a frame
  const fs::path out = farm.dir() / "out";
  const std::string pattern = (out / "frame_####.exr").string();
  auto client = farm.cli_async({"submit", scene.string(), "--coordinator", farm.address(), "-o", pattern, "--tile", "16"},
                               "submit.log");
  for (int i = 0; i < 600 && client->running() && client->log().find("frame_0000.exr: frame 0") == std::string::npos;
       ++i) {
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_NE(client->log().find("frame_0000.exr: frame 0"), std::string::npos) << client->log();
  const std::string job = job_id_from(client->log());
  client->signal(SIGINT);
  EXPECT_EQ(client->wait(10s), 128 + SIGINT) << client->log();
  const std::string said = client->log();
  EXPECT_NE(said.find("interrupted: job " + job + " keeps rendering on the farm"), std::string::npos) << said;
  EXPECT_NE(said.find("tessera watch " + job + " --coordinator " + farm.address() + " -o " + pattern),
            std::string::npos) << said;
  EXPECT_NE(said.find("tessera cancel " + job + " --coordinator " + farm.address()), std::string::npos) << said;
  // Only whole frames under their names, and no temporary file left beside them.
  for (const auto& e : fs::directory_iterator(out)) {
    EXPECT_TRUE(std::regex_match(e.path().filename().string(), std::regex("frame_000[0-2]\\.exr")))
        << e.path();
  }
  EXPECT_EQ(compare_exr(out / "frame_0000.exr", reference_frame(scene, 0, {})), "");
  std::string state;
  farm.tiles_done(job, &state);
  EXPECT_TRUE(state == "running" || state == "done") << state;
  // Coming back as the notice says: every frame, bit-identical to `tessera render`.
  const CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", pattern});
  EXPECT_EQ(w.code, 0) << w.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(scene, f, {})), "")
        << "frame " << f << "\n" << w.output;
  }
}

}  // namespace
}  // namespace tessera::farmtest

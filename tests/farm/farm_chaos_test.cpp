// SPDX-License-Identifier: Apache-2.0
// Chaos: a 10-frame job while workers are killed (SIGKILL) and restarted every couple of seconds
// and the coordinator is killed (kill -9) and restarted twice. Every frame must come out
// bit-identical to an in-process render, and the number of tiles rendered more than once is
// printed (docs/reliability.md quotes it).
//
// CI size: 64x48, 2 spp, 16 px tiles (12 tiles a frame, 120 in all), 3 single-thread workers
// slowed to 120 ms a tile so that the kills land mid-job. A longer run (more kills per frame):
// TESSERA_CHAOS_DELAY_MS=600 ctest -R FarmChaos (see docs/reliability.md).
#include <gtest/gtest.h>
#include <signal.h>

#include <cstdlib>
#include <map>
#include <random>
#include <regex>
#include <thread>
#include <tuple>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/chaos_orbit.json");
constexpr int kFrames = 10;
constexpr int kTiles = kFrames * 12;

struct RenderCounts {
  int tiles = 0;          // distinct tiles seen
  int more_than_once = 0; // tiles seen more than once
  int extra = 0;          // sightings beyond the first, summed
};

// Counts the coordinators' debug lines for one job: `what` is "result" ("result: lease L job J
// frame F tile T from worker W: ...", a render that reached a coordinator) or "lease" ("lease L
// job J frame F tile T to worker W", a render handed out; a killed worker's lease is a render lost).
RenderCounts count_lines(const std::string& logs, const std::string& what, const std::string& job) {
  std::map<std::pair<int, int>, int> n;
  const std::string suffix = what == "result" ? "from worker" : "to worker";
  // A lease of a span reads "tile A-B": each of its tiles counts.
  const std::regex re("lease [0-9]+ job " + job + " frame ([0-9]+) tile ([0-9]+)(?:-([0-9]+))? " + suffix);
  for (auto it = std::sregex_iterator(logs.begin(), logs.end(), re); it != std::sregex_iterator(); ++it) {
    const int first = std::stoi((*it)[2]);
    const int last = (*it)[3].matched ? std::stoi((*it)[3]) : first;
    for (int t = first; t <= last; ++t) ++n[{std::stoi((*it)[1]), t}];
  }
  RenderCounts c;
  for (const auto& [k, v] : n) {
    ++c.tiles;
    if (v > 1) ++c.more_than_once;
    c.extra += v - 1;
  }
  return c;
}

int delay_ms() {
  const char* e = std::getenv("TESSERA_CHAOS_DELAY_MS");
  return e && *e ? std::atoi(e) : 120;
}

TEST(FarmChaos, WorkersAndCoordinatorKilledEveryFrameStillBitIdentical) {
  Farm farm;
  farm.start_server({"--lease-timeout-ms", "2000", "--heartbeat-ms", "200"});
  const std::vector<std::string> names{"c1", "c2", "c3"};
  std::map<std::string, Process*> workers;
  for (const auto& n : names) workers[n] = &farm.start_worker(n, 1, delay_ms());
  const fs::path out = farm.dir() / "out";
  auto client = farm.cli_async({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                                (out / "frame_####.exr").string(), "--tile", "16"},
                               "submit.log");
  const std::string job = wait_job_id(*client);
  ASSERT_FALSE(job.empty()) << client->log() << farm.server_logs();

  std::mt19937 rng(8);  // fixed: the same kill schedule every run
  int worker_kills = 0, coordinator_kills = 0;
  const int restart_at[2] = {kTiles / 4, kTiles * 3 / 5};
  auto last_kill = std::chrono::steady_clock::now();
  const auto deadline = std::chrono::steady_clock::now() + 150s;
  while (client->running() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(100ms);
    if (coordinator_kills < 2) {
      std::string state;
      const int done = farm.tiles_done(job, &state);
      if (done >= restart_at[coordinator_kills] && state != "done") {
        farm.restart_server(300ms);  // kill -9, 0.3 s down, same port and data dir
        ++coordinator_kills;
        continue;
      }
    }
    if (std::chrono::steady_clock::now() - last_kill > 1500ms) {
      const std::string& victim = names[rng() % names.size()];
      workers[victim]->signal(SIGKILL);
      workers[victim]->wait(5s);
      workers[victim] = &farm.start_worker(victim, 1, delay_ms());
      ++worker_kills;
      last_kill = std::chrono::steady_clock::now();
    }
  }
  ASSERT_EQ(client->wait(60s), 0) << client->log() << farm.server_logs();
  EXPECT_EQ(coordinator_kills, 2) << "the job finished before both coordinator restarts";
  for (int f = 0; f < kFrames; ++f) {
    const fs::path got = out / ("frame_000" + std::to_string(f) + ".exr");
    EXPECT_EQ(compare_exr(got, reference_frame(kScene, f, {})), "") << "frame " << f;
  }
  std::string state;
  EXPECT_EQ(farm.tiles_done(job, &state), kTiles);
  EXPECT_EQ(state, "done");
  const std::string logs = farm.server_logs();
  EXPECT_NE(logs.find("restored 1 jobs"), std::string::npos) << logs;
  const RenderCounts results = count_lines(logs, "result", job);
  const RenderCounts leases = count_lines(logs, "lease", job);
  EXPECT_EQ(results.tiles, kTiles);
  EXPECT_EQ(leases.tiles, kTiles);
  std::printf("[chaos] %d tiles, %d worker kills, %d coordinator kills: %d tiles handed out more than once (%d extra "
              "leases: renders lost with a killed process, or speculative copies); %d tiles whose result reached a "
              "coordinator more than once (%d extra results)\n",
              kTiles, worker_kills, coordinator_kills, leases.more_than_once, leases.extra, results.more_than_once,
              results.extra);
  RecordProperty("tiles_leased_more_than_once", leases.more_than_once);
  RecordProperty("tiles_rendered_more_than_once", results.more_than_once);
}

}  // namespace
}  // namespace tessera::farmtest

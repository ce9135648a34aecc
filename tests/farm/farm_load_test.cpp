// SPDX-License-Identifier: Apache-2.0
// Load: 50 clients submit and watch tiny jobs at once on 20 workers. Every job finishes with its
// frame bit-identical to `tessera render`, every finished job leaves the coordinator's memory
// (the mechanism that bounds it), and the coordinator's RSS before and after is printed together
// with the p50/p99 time from submit to first tile (docs/reliability.md quotes them).
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");
const std::vector<std::string> kTiny{"--frames", "0", "--width", "32", "--height", "32", "--spp", "1", "--tile", "16"};

long rss_kib(int pid) {
  const std::string status = read_text("/proc/" + std::to_string(pid) + "/status");
  std::smatch m;
  if (std::regex_search(status, m, std::regex("VmRSS:\\s+([0-9]+) kB"))) return std::stol(m[1]);
  return -1;
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * double(v.size() - 1) + 0.5))];
}

TEST(FarmLoad, FiftyClientsTwentyWorkersAllFinishAndLeaveMemory) {
  constexpr int kClients = 50, kWorkers = 20;
  Farm farm;
  farm.start_server({"--log-level", "info"});
  for (int i = 0; i < kWorkers; ++i) farm.start_worker("w" + std::to_string(i));
  auto submit = [&](int i) {
    std::vector<std::string> args{"submit", kScene.string(), "--coordinator", farm.address(), "-q", "-o",
                                  (farm.dir() / ("out" + std::to_string(i)) / "f_####.exr").string()};
    args.insert(args.end(), kTiny.begin(), kTiny.end());
    return farm.cli_async(args, "client-" + std::to_string(i) + ".log");
  };
  // Warm-up: one job through every stage, then the baseline RSS.
  ASSERT_EQ(submit(1000)->wait(120s), 0) << farm.server().log();
  const long rss_before = rss_kib(farm.server().pid());

  std::vector<std::unique_ptr<Process>> clients;
  for (int i = 0; i < kClients; ++i) clients.push_back(submit(i));
  for (int i = 0; i < kClients; ++i) {
    EXPECT_EQ(clients[size_t(i)]->wait(180s), 0) << "client " << i << ": " << clients[size_t(i)]->log();
  }
  const fs::path ref = reference_frame(kScene, 0, {"--width", "32", "--height", "32", "--spp", "1"});
  for (int i = 0; i < kClients; ++i) {
    EXPECT_EQ(compare_exr(farm.dir() / ("out" + std::to_string(i)) / "f_0000.exr", ref), "") << "client " << i;
  }
  // Every job was acknowledged by its client, so none is left in memory.
  std::this_thread::sleep_for(300ms);
  CliResult list = farm.cli({"status", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(list.code, 0) << list.output;
  EXPECT_EQ(nlohmann::json::parse(list.output).size(), 0u) << list.output;
  const long rss_after = rss_kib(farm.server().pid());

  const std::string log = farm.server().log();
  std::vector<double> first;
  const std::regex re("first tile ([0-9.]+) s after submit");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), re); it != std::sregex_iterator(); ++it) {
    first.push_back(std::stod((*it)[1]));
  }
  ASSERT_EQ(first.size(), size_t(kClients + 1)) << log;
  std::printf("[load] %d clients, %d workers: submit->first tile p50 %.3f s, p99 %.3f s; coordinator RSS %ld KiB "
              "after 1 job, %ld KiB after %d more\n",
              kClients, kWorkers, percentile(first, 0.5), percentile(first, 0.99), rss_before, rss_after, kClients);
  RecordProperty("first_tile_p50_ms", int(percentile(first, 0.5) * 1000));
  RecordProperty("first_tile_p99_ms", int(percentile(first, 0.99) * 1000));
  RecordProperty("rss_after_kib", int(rss_after));
}

}  // namespace
}  // namespace tessera::farmtest

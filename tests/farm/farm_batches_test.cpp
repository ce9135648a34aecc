// SPDX-License-Identifier: Apache-2.0
// Results and assignments in batches (farm/result_batching.h): a worker gathers the results that
// finish close together into one message, and the coordinator sends each worker the leases of
// one dispatch in one message. Fewer messages; the frames must not notice.
#include <gtest/gtest.h>
#include <signal.h>

#include <regex>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");
constexpr int kFrames = 3;
constexpr int kTilesPerFrame = 24;  // 96x64 at 16 px

struct Sent {
  int results = -1;
  int messages = -1;
};

// Renders the scene's frames through one 2-thread worker started with `worker_args`, checks them
// against `tessera render`, then stops the worker and reads what it says it sent.
Sent render_and_count(const std::vector<std::string>& worker_args) {
  Farm farm;
  farm.start_server();
  Process& w = farm.start_worker("w", 2, 0, worker_args);
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (out / "frame_####.exr").string(), "--tile", "16"});
  EXPECT_EQ(r.code, 0) << r.output << farm.server().log();
  for (int f = 0; f < kFrames; ++f) {
    const fs::path got = out / ("frame_000" + std::to_string(f) + ".exr");
    EXPECT_EQ(compare_exr(got, reference_frame(kScene, f, {})), "") << "frame " << f;
  }
  w.signal(SIGTERM);
  EXPECT_EQ(w.wait(30s), 0) << w.log();
  Sent sent;
  std::smatch m;
  const std::string log = w.log();
  if (std::regex_search(log, m, std::regex(R"(sent (\d+) results in (\d+) messages)"))) {
    sent.results = std::stoi(m[1]);
    sent.messages = std::stoi(m[2]);
  }
  return sent;
}

TEST(FarmBatches, ResultsGoTogetherAndTheFramesAreThoseOfRender) {
  // A linger no tile waits out: batches end when the worker runs out of tiles on hand.
  const Sent s = render_and_count({"--result-linger-ms", "1000"});
  EXPECT_EQ(s.results, kFrames * kTilesPerFrame);
  EXPECT_GE(s.messages, 1);
  EXPECT_LT(s.messages, s.results / 2) << "results were not gathered";
}

TEST(FarmBatches, WithoutLingerEveryResultGoesAlone) {
  const Sent s = render_and_count({"--result-linger-ms", "0"});
  EXPECT_EQ(s.results, kFrames * kTilesPerFrame);
  EXPECT_EQ(s.messages, s.results);
}

}  // namespace
}  // namespace tessera::farmtest

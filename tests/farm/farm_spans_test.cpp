// SPDX-License-Identifier: Apache-2.0
// Span leases (docs/farm.md, "Lease rules"): a lease of several consecutive tiles of a frame. The
// tile stays the unit of results, so the frames must be the bits `tessera render` makes whatever
// the span size, and a worker that dies mid-span must lose only the tiles it had not returned.
#include <gtest/gtest.h>
#include <signal.h>

#include <regex>
#include <set>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");
constexpr int kFrames = 3;
constexpr int kTilesPerFrame = 96;  // 96x64 at 8 px

struct Leases {
  int leases = 0;
  int tiles = 0;
  int largest = 0;
};

// What the coordinator's debug log says it leased: "lease L job J frame F tile A[-B] to worker W".
Leases leases_in(const std::string& log) {
  Leases l;
  static const std::regex line(R"(lease \d+ job \w+ frame \d+ tile (\d+)(?:-(\d+))? to worker)");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), line); it != std::sregex_iterator(); ++it) {
    const int first = std::stoi((*it)[1]);
    const int last = (*it)[2].matched ? std::stoi((*it)[2]) : first;
    ++l.leases;
    l.tiles += last - first + 1;
    l.largest = std::max(l.largest, last - first + 1);
  }
  return l;
}

void expect_frames_of_render(const fs::path& out) {
  for (int f = 0; f < kFrames; ++f) {
    const fs::path got = out / ("frame_000" + std::to_string(f) + ".exr");
    EXPECT_EQ(compare_exr(got, reference_frame(kScene, f, {"--tile", "8"})), "") << "frame " << f;
  }
}

Leases render_with(const std::vector<std::string>& server_args) {
  Farm farm;
  std::vector<std::string> args = {"--log-level", "debug"};
  args.insert(args.end(), server_args.begin(), server_args.end());
  farm.start_server(args);
  farm.start_worker("w", 2);
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (out / "frame_####.exr").string(), "--tile", "8"});
  EXPECT_EQ(r.code, 0) << r.output << farm.server().log();
  expect_frames_of_render(out);
  return leases_in(farm.server().log());
}

TEST(FarmSpans, LeasesOfManyTilesMakeTheFramesOfRender) {
  // A long span time: once the worker has shown its rate, its leases hold many tiles.
  const Leases l = render_with({"--span-ms", "2000"});
  EXPECT_GE(l.tiles, kFrames * kTilesPerFrame);  // speculative copies may add a few
  EXPECT_GT(l.largest, 8) << "no lease held more than a few tiles";
  EXPECT_LT(l.leases, l.tiles / 4) << l.leases << " leases for " << l.tiles << " tiles";
}

TEST(FarmSpans, MaxSpanTilesOneLeasesEveryTileAlone) {
  const Leases l = render_with({"--max-span-tiles", "1"});
  EXPECT_GE(l.tiles, kFrames * kTilesPerFrame);
  EXPECT_EQ(l.largest, 1);
  EXPECT_EQ(l.leases, l.tiles);
}

TEST(FarmSpans, AWorkerKilledMidSpanLosesOnlyTheTilesItHadNotReturned) {
  Farm farm;
  farm.start_server({"--log-level", "debug", "--span-ms", "5000"});
  // Slow tiles (50 ms each after rendering) so the kill lands inside a span.
  Process& doomed = farm.start_worker("doomed", 2, 50);
  const fs::path out = farm.dir() / "out";
  auto submit = farm.cli_async({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                                (out / "frame_####.exr").string(), "--tile", "8"},
                               "submit");
  // Wait for it to be inside a span: a result in, a lease of several tiles held (the worker asks
  // for few tiles at a time when its tiles are slow, so its spans are short).
  ASSERT_TRUE(poll_until(60s, [&] {
    const std::string log = farm.server().log();
    return leases_in(log).largest >= 3 && std::regex_search(log, std::regex("result: lease .* accepted"));
  })) << farm.server().log();
  std::this_thread::sleep_for(150ms);
  doomed.signal(SIGKILL);
  doomed.wait(10s);
  farm.start_worker("rescue", 2);
  ASSERT_EQ(submit->wait(120s), 0) << submit->log() << farm.server().log();
  expect_frames_of_render(out);
  const std::string log = farm.server().log();
  // The doomed worker's returned tiles stayed done: the coordinator requeued only the rest.
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(log, m, std::regex(R"('doomed' left \(.*\): (\d+) tiles rendered, (\d+) tiles requeued)")))
      << log;
  const int rendered = std::stoi(m[1]), requeued = std::stoi(m[2]);
  EXPECT_GT(rendered, 0);
  EXPECT_GT(requeued, 0);
  EXPECT_LE(rendered + requeued, kFrames * kTilesPerFrame);
  // Every tile was accepted once: nothing the doomed worker returned was rendered again.
  static const std::regex accepted(R"(result: lease \d+ job \w+ frame (\d+) tile (\d+) from worker \d+: accepted)");
  std::set<std::pair<int, int>> tiles;
  int results = 0;
  for (auto it = std::sregex_iterator(log.begin(), log.end(), accepted); it != std::sregex_iterator(); ++it) {
    ++results;
    tiles.insert({std::stoi((*it)[1]), std::stoi((*it)[2])});
  }
  EXPECT_EQ(results, kFrames * kTilesPerFrame);
  EXPECT_EQ(tiles.size(), size_t(kFrames * kTilesPerFrame));
}

}  // namespace
}  // namespace tessera::farmtest

// SPDX-License-Identifier: Apache-2.0
// Delivery: frames land where the job says, whoever is watching. A `tessera collect` started
// after a detached job finished writes every frame; two collectors and a `tessera watch` on one
// job write each frame once; a collector killed mid-job loses its frames to the other, through a
// coordinator kill -9 and restart; frames nobody collected outlive the retention time and, at the
// limit, refuse new jobs by name. Real processes on loopback (farm_harness.h); every frame is
// compared pixel for pixel with `tessera render`'s (and with idiff -fail 0 where OpenImageIO's
// tools are installed).
#include <gtest/gtest.h>

#include <csignal>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

const fs::path kScene = source("tests/farm/delivery_orbit.json");  // 20 frames, 64x48
constexpr int kFrames = 20;

std::string frame_name(int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "f_%04d.exr", frame);
  return name;
}

// How many times each frame was written, from the "PATH: frame N: ..." lines clients print.
std::map<int, int> frames_written(const std::string& output) {
  std::map<int, int> n;
  static const std::regex line(R"(: frame (\d+): [0-9.]+ s,)");
  for (auto it = std::sregex_iterator(output.begin(), output.end(), line); it != std::sregex_iterator(); ++it) {
    ++n[std::stoi((*it)[1])];
  }
  return n;
}

// Every frame in `dir` whole and equal to tessera render's, and no other file under a frame's name.
void expect_frames_match_render(const fs::path& dir) {
  const bool idiff = std::system("command -v idiff > /dev/null 2>&1") == 0;
  for (int f = 0; f < kFrames; ++f) {
    const fs::path got = dir / frame_name(f);
    const fs::path ref = reference_frame(kScene, f, {});
    EXPECT_EQ(compare_exr(got, ref), "") << "frame " << f;
    if (idiff) {
      const std::string cmd = "idiff -fail 0 -warn 0 '" + got.string() + "' '" + ref.string() + "' > /dev/null 2>&1";
      EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    }
  }
}

std::vector<std::string> submit_args(const Farm& farm, const fs::path& share) {
  return {"submit",
          kScene.string(),
          "--coordinator",
          farm.address(),
          "--detach",
          "--tile",
          "16",
          "-o",
          (share / "f_####.exr").string()};
}

// `tessera collect` in the background; `once`: it exits when the jobs it found are delivered.
std::unique_ptr<Process> start_collector(Farm& farm, const std::string& log_name, bool once) {
  std::vector<std::string> args{"collect", "--coordinator", farm.address(), "--poll", "0.2"};
  if (once) args.push_back("--once");
  return farm.cli_async(args, log_name);
}

// Submits the 20-frame job with --detach and waits until the farm has rendered it, no client attached.
void submit_detached_until_done(Farm& farm, const fs::path& share, std::string* job) {
  CliResult sub = farm.cli(submit_args(farm, share));
  ASSERT_EQ(sub.code, 0) << sub.output;
  *job = job_id_from(sub.output);
  ASSERT_TRUE(poll_until(std::chrono::seconds(120), [&] {
    std::string state;
    farm.tiles_done(*job, &state);
    return state == "done";
  })) << farm.server_logs();
}

TEST(FarmDelivery, ACollectorStartedAfterADetachedJobEndedWritesEveryFrameInTheRecordedFormats) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w", 2);
  const fs::path share = farm.dir() / "share";
  std::string job;
  ASSERT_NO_FATAL_FAILURE(submit_detached_until_done(farm, share, &job));
  EXPECT_FALSE(fs::exists(share / frame_name(0))) << "nobody was attached: nothing written yet";
  CliResult st = farm.cli({"status", "--coordinator", farm.address()});
  EXPECT_NE(st.output.find("undelivered: 20 finished frames"), std::string::npos) << st.output;
  // A second job recorded in another format: tone-mapped PNGs.
  CliResult png = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--frames", "0-2",
                            "-o", (share / "png" / "p_####.png").string(), "--tonemap", "aces", "--exposure", "0.5"});
  ASSERT_EQ(png.code, 0) << png.output;

  CliResult collect = farm.cli({"collect", "--coordinator", farm.address(), "--once", "--poll", "0.2"});
  ASSERT_EQ(collect.code, 0) << collect.output << farm.server_logs();
  int written = 0;
  for (const auto& [f, n] : frames_written(collect.output)) written += n;
  EXPECT_EQ(written, kFrames + 3) << collect.output;
  expect_frames_match_render(share);
  for (int f = 0; f < 3; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "p_%04d.png", f);
    const fs::path ref = farm.dir() / (std::string("ref_") + name);
    ASSERT_EQ(farm.cli({"render", kScene.string(), "-o", ref.string(), "--frame", std::to_string(f), "-q", "--tonemap",
                        "aces", "--exposure", "0.5"})
                  .code,
              0);
    EXPECT_EQ(read_text(share / "png" / name), read_text(ref)) << name << " differs from tessera render's PNG";
  }
  // Delivered: the job left memory, the backlog is empty, and a second collector finds nothing.
  st = farm.cli({"status", "--coordinator", farm.address()});
  EXPECT_EQ(st.output.find("undelivered"), std::string::npos) << st.output;
  CliResult again = farm.cli({"collect", "--coordinator", farm.address(), "--once", "--poll", "0.2"});
  EXPECT_EQ(again.code, 0) << again.output;
  EXPECT_TRUE(frames_written(again.output).empty()) << again.output;
}

TEST(FarmDelivery, TwoCollectorsAndAWatchWriteEachFrameOnce) {
  Farm farm;
  farm.start_server();
  // 20 ms a tile, 240 tiles: the job runs for seconds, so every deliverer attaches while most
  // frames are still to come and each gets a share, however slow the machine starts processes.
  farm.start_worker("w", 1, 20);
  const fs::path share = farm.dir() / "share";
  CliResult sub = farm.cli(submit_args(farm, share));
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  auto a = start_collector(farm, "collect-a", true);
  auto b = start_collector(farm, "collect-b", true);
  auto w = farm.cli_async({"watch", job, "--coordinator", farm.address(), "-q"}, "watch");
  ASSERT_EQ(w->wait(std::chrono::seconds(180)), 0) << w->log() << farm.server_logs();
  ASSERT_EQ(a->wait(std::chrono::seconds(60)), 0) << a->log();
  ASSERT_EQ(b->wait(std::chrono::seconds(60)), 0) << b->log();
  std::map<int, int> total;
  std::string all;
  int writers = 0;
  for (const std::string& log : {a->log(), b->log(), w->log()}) {
    const auto mine = frames_written(log);
    for (const auto& [f, n] : mine) total[f] += n;
    writers += !mine.empty();
    all += log + "\n----\n";
  }
  // The frames are shared out, not taken by the first to attach (each frame is written and
  // acknowledged before the next one starts: deliverers take turns).
  EXPECT_GE(writers, 2) << all;
  for (int f = 0; f < kFrames; ++f) {
    EXPECT_EQ(total[f], 1) << "frame " << f << " written " << total[f] << " times\n" << all;
  }
  EXPECT_EQ(total.size(), size_t(kFrames)) << all;
  expect_frames_match_render(share);
}

TEST(FarmDelivery, AKilledCollectorsFramesGoToTheOtherThroughACoordinatorRestart) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w", 1, 20);  // as above: both collectors attach while the job runs
  const fs::path share = farm.dir() / "share";
  CliResult sub = farm.cli(submit_args(farm, share));
  ASSERT_EQ(sub.code, 0) << sub.output;
  auto a = start_collector(farm, "collect-a", false);
  auto b = start_collector(farm, "collect-b", true);
  // Once each has written a frame, A holds another one in progress: kill -9 it mid-job, then the
  // coordinator too. B re-attaches and delivers the rest, A's included.
  ASSERT_TRUE(poll_until(std::chrono::seconds(120),
                         [&] { return !frames_written(a->log()).empty() && !frames_written(b->log()).empty(); }))
      << a->log() << b->log() << farm.server_logs();
  a->signal(SIGKILL);
  a->wait(std::chrono::seconds(10));
  const size_t by_a = frames_written(a->log()).size();
  farm.restart_server();
  ASSERT_EQ(b->wait(std::chrono::seconds(180)), 0) << b->log() << farm.server_logs();
  const auto by_b = frames_written(b->log());
  EXPECT_LT(by_a, size_t(kFrames));
  EXPECT_GE(by_a + by_b.size(), size_t(kFrames)) << a->log() << b->log();
  // Whatever was written twice (a frame written and not yet acknowledged when its collector or the
  // coordinator died) was written whole and the same: a user sees every frame once, complete. A
  // collector killed while writing leaves its temporary file beside the frame (NAME.tmp.XXXXXX.exr),
  // never a partial file under the frame's name.
  expect_frames_match_render(share);
  const std::regex frame(R"(f_\d{4}\.exr)"), temporary(R"(f_\d{4}\.tmp\.\w{6}\.exr)");
  for (const auto& e : fs::directory_iterator(share)) {
    const std::string name = e.path().filename().string();
    EXPECT_TRUE(std::regex_match(name, frame) || std::regex_match(name, temporary)) << "a stray file: " << name;
  }
}

// With named client tokens a collector delivers the jobs its identity may: another identity's job
// is named once and left alone (not retried, not an error), --owner picks jobs by owner, and an
// administrator's collector delivers anyone's.
TEST(FarmDelivery, ACollectorDeliversTheJobsItsTokenMayAndNamesTheOthersOnce) {
  Farm farm;
  std::ofstream(farm.dir() / "clients") << "alice: alice-secret\nbob: bob-secret\nops: ops-secret\n";
  for (const char* who : {"alice", "bob", "ops"})
    std::ofstream(farm.dir() / (std::string(who) + ".token")) << who << "-secret";
  const auto as = [&](const char* who) {
    return std::vector<std::string>{"--coordinator", farm.address(), "--token-file",
                                    (farm.dir() / (std::string(who) + ".token")).string()};
  };
  const auto cli_as = [&](const char* who, std::vector<std::string> args) {
    const auto id = as(who);
    args.insert(args.end(), id.begin(), id.end());
    return farm.cli(args);
  };
  farm.start_server({"--client-tokens", (farm.dir() / "clients").string(), "--admin", "token:ops"});
  farm.start_worker("w", 2);
  const fs::path share = farm.dir() / "share";
  CliResult sub = cli_as(
      "alice", {"submit", kScene.string(), "--detach", "--frames", "0-2", "-o", (share / "f_####.exr").string()});
  ASSERT_EQ(sub.code, 0) << sub.output;
  const std::string job = job_id_from(sub.output);
  ASSERT_TRUE(poll_until(std::chrono::seconds(120), [&] {
    CliResult st = cli_as("alice", {"status", job, "--json"});
    return st.code == 0 && nlohmann::json::parse(st.output).at("state") == "done";
  })) << farm.server_logs();
  EXPECT_EQ(nlohmann::json::parse(cli_as("alice", {"status", job, "--json"}).output).at("owner"), "token:alice");

  CliResult bob = cli_as("bob", {"collect", "--once", "--poll", "0.2"});
  EXPECT_EQ(bob.code, 0) << bob.output;
  EXPECT_NE(bob.output.find("job " + job + " is not collected here"), std::string::npos) << bob.output;
  EXPECT_TRUE(frames_written(bob.output).empty()) << bob.output;
  CliResult bob_own = cli_as("bob", {"collect", "--once", "--poll", "0.2", "--owner", "token:bob"});
  EXPECT_EQ(bob_own.code, 0) << bob_own.output;
  EXPECT_EQ(bob_own.output.find(job), std::string::npos) << "--owner token:bob leaves alice's job alone";
  EXPECT_FALSE(fs::exists(share / frame_name(0)));

  CliResult ops = cli_as("ops", {"collect", "--once", "--poll", "0.2", "--owner", "token:alice"});
  ASSERT_EQ(ops.code, 0) << ops.output << farm.server_logs();
  EXPECT_EQ(frames_written(ops.output).size(), 3u) << ops.output;
  for (int f = 0; f < 3; ++f) EXPECT_EQ(compare_exr(share / frame_name(f), reference_frame(kScene, f, {})), "") << f;
}

TEST(FarmDelivery, FramesNobodyCollectedOutliveRetentionAndAtTheLimitRefuseNewJobsByName) {
  Farm farm;
  // Retention of about a second; a limit of one byte: the first undelivered frame reaches it.
  farm.start_server({"--retention-hours", "0.0003", "--max-undelivered-gb", "0.000000001"});
  farm.start_worker("w", 2);
  const fs::path share = farm.dir() / "share";
  std::string job;
  ASSERT_NO_FATAL_FAILURE(submit_detached_until_done(farm, share, &job));
  // Well past retention: the job is still in memory, its frames kept, and the log says why.
  ASSERT_TRUE(poll_until(std::chrono::seconds(30), [&] {
    return farm.server_logs().find("job " + job + " ended more than the retention time ago") != std::string::npos;
  })) << farm.server_logs();
  std::this_thread::sleep_for(std::chrono::seconds(2));
  CliResult st = farm.cli({"status", "--coordinator", farm.address()});
  EXPECT_NE(st.output.find(job), std::string::npos) << st.output;
  EXPECT_NE(st.output.find("undelivered: 20 finished frames"), std::string::npos) << st.output;

  CliResult refused = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach"});
  EXPECT_NE(refused.code, 0) << refused.output;
  EXPECT_NE(refused.output.find("--max-undelivered-gb"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find(job), std::string::npos) << "the message names the job to collect: " << refused.output;

  CliResult collect = farm.cli({"collect", "--coordinator", farm.address(), "--once", "--poll", "0.2"});
  ASSERT_EQ(collect.code, 0) << collect.output << farm.server_logs();
  expect_frames_match_render(share);
  // A job whose frames nobody wants: `tessera cancel --discard` drops them, and frees the room.
  std::string unwanted;
  ASSERT_NO_FATAL_FAILURE(submit_detached_until_done(farm, farm.dir() / "unwanted", &unwanted));
  refused = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach"});
  EXPECT_NE(refused.output.find(unwanted), std::string::npos) << refused.output;
  CliResult discard = farm.cli({"cancel", unwanted, "--discard", "--coordinator", farm.address()});
  ASSERT_EQ(discard.code, 0) << discard.output;
  st = farm.cli({"status", "--coordinator", farm.address()});
  EXPECT_EQ(st.output.find("undelivered"), std::string::npos) << st.output;
  EXPECT_FALSE(fs::exists(farm.dir() / "unwanted")) << "discarded frames are never written";
  // Delivered or discarded: nothing is held, and the next job is accepted; one without an output
  // is not kept past retention.
  CliResult plain = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--frames", "0"});
  ASSERT_EQ(plain.code, 0) << plain.output;
  const std::string plain_job = job_id_from(plain.output);
  EXPECT_TRUE(poll_until(std::chrono::seconds(60), [&] {
    return farm.server_logs().find("job " + plain_job + " left memory (retention time passed)") != std::string::npos;
  })) << farm.server_logs();
}

}  // namespace
}  // namespace tessera::farmtest

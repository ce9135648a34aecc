// SPDX-License-Identifier: Apache-2.0
// Stop signals with real processes: SIGINT and SIGTERM are taken by the one thread that waits for
// them (farm/stop_signals.h), so a stop is always the clean one. A thread that does not block them
// (gRPC starts its executor and timer threads as soon as credentials are made) lets the kernel
// end the process by the default action instead (CI once saw a coordinator's clean stop end as a
// kill by SIGTERM, exit 143, which loses the commit window's tiles).
#include <gtest/gtest.h>
#include <httplib.h>
#include <signal.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "farm_harness.h"
#include "test_pki.h"

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

// `tessera status JOB --json` with `flags` (TLS, token): tiles done, or -1 when it fails.
int tiles_done(Farm& farm, const std::string& job, const std::vector<std::string>& flags) {
  std::vector<std::string> args{"status", job, "--json"};
  args.insert(args.end(), flags.begin(), flags.end());
  const CliResult r = farm.cli(args, 20s);
  if (r.code != 0) return -1;
  return nlohmann::json::parse(r.output).at("tiles_done").get<int>();
}

// A busy coordinator with every option on (TLS, client and worker tokens, --http-listen with the
// monitor and the Prometheus metrics, a data directory, a commit window that always holds
// finished tiles), stopped by SIGTERM while two workers render, again and again: every stop is
// the clean one (exit 0, "stopped"), and the job's frames are whole and bit-identical after.
// The metrics used to be destroyed before the job store wrote its last batch and reported it to
// them (Histogram::Observe on freed memory: exit 139 or 134 in most stops).
TEST(FarmSignals, SigtermStopsABusyCoordinatorWithEveryOptionOnCleanlyEveryTime) {
  const fs::path scene = source("tests/farm/whitted_orbit.json");  // 96x64, 3 frames
  Farm farm;
  const Pki pki = make_pki(farm.dir());
  std::ofstream(farm.dir() / "client.token") << "client-secret-sigterm\n";
  std::ofstream(farm.dir() / "worker.token") << "worker-secret-sigterm\n";
  const std::vector<std::string> server_args{
      "--http-listen", "127.0.0.1:0", "--tls-cert", pki.server_cert.string(), "--tls-key", pki.server_key.string(),
      "--client-token-file", (farm.dir() / "client.token").string(), "--worker-token-file",
      (farm.dir() / "worker.token").string(), "--commit-window-ms", "3000"};
  farm.start_server(server_args);
  const std::vector<std::string> worker_args{"--tls-ca", pki.ca.string(), "--token-file",
                                             (farm.dir() / "worker.token").string()};
  farm.start_worker("w1", 1, 80, worker_args);  // 80 ms a tile: the job outlasts the stops
  farm.start_worker("w2", 1, 80, worker_args);
  const std::vector<std::string> client{"--coordinator", farm.address(), "--tls-ca", pki.ca.string(), "--token-file",
                                        (farm.dir() / "client.token").string()};
  std::vector<std::string> submit{"submit", scene.string(), "--tile", "8", "--detach"};  // 288 tiles
  submit.insert(submit.end(), client.begin(), client.end());
  const CliResult s = farm.cli(submit);
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  constexpr int kStops = 4;
  int done = 0;
  for (int stop = 1; stop <= kStops; ++stop) {
    SCOPED_TRACE("stop " + std::to_string(stop));
    // Busy: tiles are being finished (and sit in the commit window) when the signal comes.
    const int before = done;
    for (int i = 0; i < 600 && done < before + 12; ++i) {
      std::this_thread::sleep_for(50ms);
      done = std::max(done, tiles_done(farm, job, client));
    }
    ASSERT_GE(done, before + 12) << "the workers rendered nothing\n" << farm.server_logs();
    ASSERT_LT(done, 288) << "the job ended before stop " << stop << ": make its tiles slower";
    // The monitor has a reader, so its feed is active too. (The port is taken as a number: a
    // match's sub-matches point into the string searched, which must outlive them.)
    const int port = [&] {
      const std::string log = farm.server().log();
      std::smatch m;
      return std::regex_search(log, m, std::regex("monitor on https://127\\.0\\.0\\.1:([0-9]+)/")) ? std::stoi(m[1]) : 0;
    }();
    ASSERT_NE(port, 0) << farm.server().log();
    httplib::SSLClient https("127.0.0.1", port);
    https.enable_server_certificate_verification(false);
    auto page = https.Get("/api/farm", {{"Authorization", "Bearer client-secret-sigterm"}});
    ASSERT_TRUE(page) << httplib::to_string(page.error());
    EXPECT_EQ(page->status, 200);
    farm.server().signal(SIGTERM);
    const int code = farm.server().wait(60s);
    const std::string log = farm.server().log();
    EXPECT_EQ(code, 0) << log.substr(log.size() > 4000 ? log.size() - 4000 : 0);
    EXPECT_NE(log.find("info stopped"), std::string::npos) << log.substr(log.size() > 4000 ? log.size() - 4000 : 0);
    if (stop < kStops) farm.start_server(server_args);  // same port and data: the workers come back
  }
  // The data is intact: a coordinator started on it serves every frame, bit-identical.
  farm.start_server(server_args);
  const fs::path out = farm.dir() / "out";
  std::vector<std::string> watch{"watch", job, "-o", (out / "frame_####.exr").string()};
  watch.insert(watch.end(), client.begin(), client.end());
  const CliResult w = farm.cli(watch);
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(scene, f, {})), "")
        << "frame " << f;
  }
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

// SPDX-License-Identifier: Apache-2.0
// tessera-worker: renders tiles for a Tessera coordinator.
#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <thread>

#include "connection.h"
#include "cpu_quota.h"
#include "farm/command_line.h"
#include "farm/stop_signals.h"

int main(int argc, char** argv) {
  const sigset_t sigs = tessera::farm::block_stop_signals();  // first, before any thread starts
  using namespace tessera::worker;
  WorkerOptions o;
  const char* env = std::getenv("TESSERA_COORDINATOR");
  if (env && *env) o.coordinator = env;
  o.threads = available_cores();
  char host[256] = "worker";
  gethostname(host, sizeof host);
  o.name = std::string(host) + "-" + std::to_string(getpid());
  std::string cache = (std::filesystem::temp_directory_path() / "tessera-worker-cache").string();
  std::string log_level = "info";

  CLI::App app{"tessera-worker: renders tiles for a Tessera render farm coordinator"};
  app.add_option("--coordinator", o.coordinator, "Coordinator HOST:PORT (env TESSERA_COORDINATOR)")
      ->capture_default_str();
  app.add_option("--threads", o.threads,
                 "Render threads (env TESSERA_THREADS; default: the cores this process may use, "
                 "counting CPU affinity and a container's CPU quota)")
      ->envname("TESSERA_THREADS")
      ->check(CLI::Range(1, 4096));
  app.add_option("--name", o.name, "Name shown by `tessera workers` (default: host-pid)");
  app.add_option("--cache-dir", cache, "Where fetched scene bundles are kept")->capture_default_str();
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  int linger_ms = int(o.batching.linger.count());
  app.add_option("--result-linger-ms", linger_ms,
                 "How long a finished tile may wait for others finishing beside it, to go to the coordinator "
                 "in one message (0: each alone). A batch goes at once when the worker has nothing else to "
                 "render")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  double idle_s = 0;
  app.add_option("--exit-when-idle", idle_s,
                 "Leave, exit status 0, after this many seconds without a tile (connected or not; the same clean "
                 "leave as SIGTERM), so a batch allocation or a Kubernetes Job ends with the farm's queue. "
                 "0: never")
      ->envname("TESSERA_EXIT_WHEN_IDLE")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e7));
  app.add_option("--test-delay-ms", o.extra_delay_ms, "Testing only: sleep this long after each tile")
      ->check(CLI::Range(0, 60000));
  app.add_option("--test-fault", o.test_fault,
                 "Testing only: send bad results (nan, wrong-size, stale lease, no-scene, negative-variance, "
                 "nan-seconds, no-block-stats: a frame-target tile without its statistics, absurd-seconds, "
                 "absurd-spp, other-frame: the next frame's pixels under its number, other-job, "
                 "long-reason: a 20 MB failure reason) to exercise the coordinator's refusal and per-job "
                 "blocklist, honest results padded with 1 MiB of unknown fields (padded), or a session that "
                 "takes tiles and never renders them (idle)")
      ->check(CLI::IsMember({"nan", "wrong-size", "stale", "no-scene", "negative-variance", "nan-seconds", "padded",
                             "no-block-stats", "absurd-seconds", "absurd-spp", "other-frame", "other-job",
                             "long-reason", "idle"}));
  std::string token_file;
  app.add_option("--token-file", token_file, "File holding the worker token (else env TESSERA_WORKER_TOKEN)")
      ->group("Security");
  app.add_option("--tls-ca", o.security.tls_ca, "PEM CA certificate of the coordinator: connect with TLS")
      ->group("Security");
  app.add_option("--tls-cert", o.security.tls_cert, "PEM client certificate (coordinator with client certificates)")
      ->group("Security");
  app.add_option("--tls-key", o.security.tls_key, "PEM private key of --tls-cert")->group("Security");
  app.set_version_flag("--version", "tessera-worker 0.1.0");
  if (const std::optional<int> rc = tessera::farm::parse_command_line(app, argc, argv)) return *rc;
  o.cache_dir = cache;
  o.batching.linger = std::chrono::milliseconds(linger_ms);
  o.exit_when_idle = std::chrono::milliseconds(int64_t(idle_s * 1000));
  try {
    o.security.token = tessera::farm::read_token(token_file, "TESSERA_WORKER_TOKEN");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tessera-worker: %s\n", e.what());
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ [" + o.name + "] %v");

  std::unique_ptr<WorkerConnection> conn;
  try {
    conn = std::make_unique<WorkerConnection>(o);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  // First SIGTERM/SIGINT: leave cleanly (return unstarted tiles, finish running ones).
  // A second one: leave now.
  std::atomic<bool> ended{false};
  std::thread signals([&] {
    // Waits in steps so that it ends with run() when the worker leaves by itself (--exit-when-idle).
    const timespec step{0, 200'000'000};
    int sig = -1;
    while (!ended && (sig = sigtimedwait(&sigs, nullptr, &step)) < 0) {
    }
    if (sig < 0) return;
    spdlog::info("signal {}: finishing current tiles and leaving (again to quit at once)", sig);
    std::thread([&] { std::_Exit(128 + tessera::farm::wait_for_signal(sigs)); }).detach();
    conn->request_stop();
  });
  const int rc = conn->run();
  ended = true;
  signals.join();
  return rc;
}

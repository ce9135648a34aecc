// SPDX-License-Identifier: Apache-2.0
// Reconnecting after a coordinator restart: a worker whose own backoff has
// grown to several seconds must still be back within about a second of the coordinator
// listening again, because it waits for the channel to connect rather than sleeping its backoff;
// over plaintext and over TLS.
#include <gtest/gtest.h>

#include <regex>
#include <thread>

#include "farm_harness.h"
#include "test_pki.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;
using Steady = std::chrono::steady_clock;

// Starts the coordinator with `server_args` and a worker with `worker_args`, stops the
// coordinator until the worker's backoff has grown past 5 s, starts it again, and checks the
// worker is back well before its backoff would have let it.
void expect_worker_back_soon(Farm& farm, const std::vector<std::string>& server_args,
                             const std::vector<std::string>& worker_args) {
  farm.start_server(server_args);
  Process& worker = farm.start_worker("w1", 1, 0, worker_args);
  const auto joined = [&](Process& server) { return server.log().find("'w1' joined") != std::string::npos; };
  for (int i = 0; i < 400 && !joined(farm.server()); ++i) std::this_thread::sleep_for(25ms);
  ASSERT_TRUE(joined(farm.server())) << farm.server().log();
  farm.stop_server();
  // Wait until the worker's backoff has grown to 6 s or more (200 ms doubling: 6.4 s on the
  // sixth attempt), then start the coordinator at once: a worker that slept its backoff would
  // need at least 4.8 s more (6.4 s less 20 % jitter).
  const std::regex grown("reconnecting to \\S+ in ([0-9.]+) s");
  bool long_wait = false;
  for (int i = 0; i < 1200 && !long_wait; ++i) {
    const std::string log = worker.log();
    for (std::sregex_iterator it(log.begin(), log.end(), grown), end; it != end; ++it) {
      long_wait |= std::stod((*it)[1]) >= 5.0;
    }
    if (!long_wait) std::this_thread::sleep_for(25ms);
  }
  ASSERT_TRUE(long_wait) << worker.log();
  farm.start_server(farm.server_extra());
  const auto listening = Steady::now();
  while (!joined(farm.server()) && Steady::now() - listening < 30s) std::this_thread::sleep_for(20ms);
  const double seconds = std::chrono::duration<double>(Steady::now() - listening).count();
  ASSERT_TRUE(joined(farm.server())) << farm.server().log();
  std::printf("worker back %.2f s after the coordinator listened\n", seconds);
  // The promise is 2 s; the bound leaves room for a loaded machine and still fails a worker
  // that sleeps its backoff (>= 4.8 s here).
  EXPECT_LT(seconds, 4.0) << worker.log();
}

TEST(FarmReconnect, WorkerIsBackSoonAfterTheCoordinatorListensWhateverItsBackoff) {
  Farm farm;
  expect_worker_back_soon(farm, {}, {});
}

// The same over TLS: the wait for the channel to connect includes the handshake, and a channel
// that failed its handshakes while the coordinator was down must not keep failing.
TEST(FarmReconnect, OverTlsTheWorkerIsBackSoonToo) {
  Farm farm;
  const Pki pki = make_pki(farm.dir());
  expect_worker_back_soon(farm, {"--tls-cert", pki.server_cert.string(), "--tls-key", pki.server_key.string()},
                          {"--tls-ca", pki.ca.string()});
  EXPECT_NE(farm.server_logs().find("security: TLS"), std::string::npos) << farm.server_logs();
}

}  // namespace
}  // namespace tessera::farmtest

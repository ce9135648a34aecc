// SPDX-License-Identifier: Apache-2.0
// When and how a worker tries its coordinator again after a session ends. Exponential backoff
// (doubling from `initial` up to `max`), started over by every session the coordinator accepted,
// with jitter so that a restarted coordinator is not hit by every worker at the same instant.
#pragma once

#include <chrono>

namespace tessera::worker {

class ReconnectPolicy {
 public:
  // The jitter factor is drawn uniformly from [kMinJitter, kMaxJitter).
  static constexpr double kMinJitter = 0.8, kMaxJitter = 1.2;

  ReconnectPolicy(std::chrono::milliseconds initial, std::chrono::milliseconds max)
      : initial_(initial), max_(max), backoff_(initial) {}

  // The wait before the next try, after a session that the coordinator `accepted` (or not: it
  // refused us, or was not there at all), scaled by `jitter`.
  std::chrono::milliseconds next_wait(bool accepted, double jitter);

  // How to spend that wait. A channel still connected means the coordinator is up but refused
  // the session (a bad token, a name in use): wait it out, that is what the backoff is for. A
  // channel not connected means the coordinator is away: try again as soon as it listens, not when
  // the backoff ends (gRPC keeps reconnecting by itself, at most a second apart).
  enum class Wait { kFullBackoff, kUntilCoordinatorListens };
  static Wait how_to_wait(bool channel_connected) {
    return channel_connected ? Wait::kFullBackoff : Wait::kUntilCoordinatorListens;
  }

 private:
  std::chrono::milliseconds initial_, max_, backoff_;
};

}  // namespace tessera::worker

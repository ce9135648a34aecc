// SPDX-License-Identifier: Apache-2.0
// Warnings about what a peer sent, rate limited per peer: a worker that floods the coordinator
// with bad results (results for jobs that do not exist, leases it never held) gets one log line a
// second, and the next line says how many were left out, so one peer cannot grow the log without
// bound. spdlog has no per-key limiter, hence this one. Not thread-safe: the coordinator calls it
// under its mutex.
#pragma once

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>

namespace tessera::server {

class PeerWarnings {
 public:
  using Clock = std::chrono::steady_clock;
  explicit PeerWarnings(Clock::duration interval = std::chrono::seconds(1)) : interval_(interval) {}

  // Logs the warning unless this peer had one within the interval (then counts it as left out).
  template <class... Args>
  void warn(uint64_t peer, spdlog::format_string_t<Args...> fmt, Args&&... args) {
    Entry& e = entries_[peer];
    const Clock::time_point now = Clock::now();
    if (e.logged && now - *e.logged < interval_) {
      ++e.suppressed;
      return;
    }
    const std::string line = fmt::format(fmt, std::forward<Args>(args)...);
    if (e.suppressed > 0) {
      spdlog::warn("{} ({} more such warnings about worker {} left out of the log)", line, e.suppressed, peer);
    } else {
      spdlog::warn("{}", line);
    }
    e.logged = now;
    e.suppressed = 0;
  }
  // A peer that left: says how many of its warnings were left out since the last line, and its
  // entry goes (the map stays as large as the peers connected).
  void forget(uint64_t peer) {
    auto it = entries_.find(peer);
    if (it == entries_.end()) return;
    if (it->second.suppressed > 0) {
      spdlog::warn("{} more such warnings about worker {} were left out of the log", it->second.suppressed, peer);
    }
    entries_.erase(it);
  }

 private:
  struct Entry {
    std::optional<Clock::time_point> logged;
    uint64_t suppressed = 0;
  };
  Clock::duration interval_;
  std::map<uint64_t, Entry> entries_;
};

}  // namespace tessera::server

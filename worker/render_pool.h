// SPDX-License-Identifier: Apache-2.0
// A fixed pool of render threads fed from one queue. Tasks carry a key (the lease id and the tile
// index: a span lease posts one task per tile) so that unstarted ones can be withdrawn when the
// coordinator revokes a lease or one tile of it, or the worker shuts down.
#pragma once

#include <compare>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace tessera::worker {

// One tile of one lease: what a task renders.
struct TaskKey {
  uint64_t lease = 0;
  int tile = 0;  // the tile's index within its frame
  auto operator<=>(const TaskKey&) const = default;
};

class RenderPool {
 public:
  explicit RenderPool(int threads);
  ~RenderPool();
  RenderPool(const RenderPool&) = delete;
  RenderPool& operator=(const RenderPool&) = delete;

  void post(TaskKey key, std::function<void()> task);
  // Withdraws every unstarted task of the lease; returns how many (0 if all started or none existed).
  size_t remove(uint64_t lease);
  // Withdraws the unstarted task of this tile of the lease; false if it already started (or never existed).
  bool remove(uint64_t lease, int tile);
  // Withdraws every unstarted task and returns their keys, in the order they were posted.
  std::vector<TaskKey> remove_all();
  // Blocks until no task is queued or running.
  void wait_idle();
  int threads() const { return int(threads_.size()); }
  // Tasks posted and not started.
  size_t queued();
  // Tasks posted and not finished (queued or running).
  size_t busy();

 private:
  void run();
  void notify_if_idle_locked();
  std::mutex mu_;
  std::condition_variable cv_, idle_cv_;
  std::deque<std::pair<TaskKey, std::function<void()>>> queue_;
  int running_ = 0;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace tessera::worker

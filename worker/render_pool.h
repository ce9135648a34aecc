// SPDX-License-Identifier: Apache-2.0
// A fixed pool of render threads fed from one queue. Tasks carry a key (the lease id) so that
// unstarted ones can be withdrawn when the coordinator revokes them or the worker shuts down.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace tessera::worker {

class RenderPool {
 public:
  explicit RenderPool(int threads);
  ~RenderPool();
  RenderPool(const RenderPool&) = delete;
  RenderPool& operator=(const RenderPool&) = delete;

  void post(uint64_t key, std::function<void()> task);
  // Withdraws an unstarted task; false if it already started (or never existed).
  bool remove(uint64_t key);
  // Withdraws every unstarted task and returns their keys.
  std::vector<uint64_t> remove_all();
  // Blocks until no task is queued or running.
  void wait_idle();
  int threads() const { return int(threads_.size()); }
  // Tasks posted and not started.
  size_t queued();
  // Tasks posted and not finished (queued or running).
  size_t busy();

 private:
  void run();
  std::mutex mu_;
  std::condition_variable cv_, idle_cv_;
  std::deque<std::pair<uint64_t, std::function<void()>>> queue_;
  int running_ = 0;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace tessera::worker

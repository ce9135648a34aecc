// SPDX-License-Identifier: Apache-2.0
#include "render_pool.h"

#include <algorithm>

namespace tessera::worker {

RenderPool::RenderPool(int threads) {
  for (int i = 0; i < std::max(1, threads); ++i) threads_.emplace_back([this] { run(); });
}

RenderPool::~RenderPool() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
    queue_.clear();
  }
  cv_.notify_all();
  for (auto& t : threads_) t.join();
}

void RenderPool::post(TaskKey key, std::function<void()> task) {
  {
    std::lock_guard lock(mu_);
    queue_.emplace_back(key, std::move(task));
  }
  cv_.notify_one();
}

void RenderPool::notify_if_idle_locked() {
  if (queue_.empty() && running_ == 0) idle_cv_.notify_all();
}

size_t RenderPool::remove(uint64_t lease) {
  std::lock_guard lock(mu_);
  const size_t n = std::erase_if(queue_, [&](const auto& t) { return t.first.lease == lease; });
  if (n > 0) notify_if_idle_locked();
  return n;
}

bool RenderPool::remove(uint64_t lease, int tile) {
  std::lock_guard lock(mu_);
  const TaskKey key{lease, tile};
  auto it = std::find_if(queue_.begin(), queue_.end(), [&](const auto& t) { return t.first == key; });
  if (it == queue_.end()) return false;
  queue_.erase(it);
  notify_if_idle_locked();
  return true;
}

std::vector<TaskKey> RenderPool::remove_all() {
  std::lock_guard lock(mu_);
  std::vector<TaskKey> keys;
  keys.reserve(queue_.size());
  for (const auto& t : queue_) keys.push_back(t.first);
  queue_.clear();
  notify_if_idle_locked();
  return keys;
}

size_t RenderPool::queued() {
  std::lock_guard lock(mu_);
  return queue_.size();
}

size_t RenderPool::busy() {
  std::lock_guard lock(mu_);
  return queue_.size() + size_t(running_);
}

void RenderPool::wait_idle() {
  std::unique_lock lock(mu_);
  idle_cv_.wait(lock, [this] { return queue_.empty() && running_ == 0; });
}

void RenderPool::run() {
  std::unique_lock lock(mu_);
  while (true) {
    cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    auto task = std::move(queue_.front().second);
    queue_.pop_front();
    ++running_;
    lock.unlock();
    task();
    lock.lock();
    --running_;
    notify_if_idle_locked();
  }
}

}  // namespace tessera::worker

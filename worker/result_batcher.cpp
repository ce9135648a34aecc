// SPDX-License-Identifier: Apache-2.0
#include "result_batcher.h"

namespace tessera::worker {

namespace v1 = tessera::v1;

ResultBatcher::ResultBatcher(farm::ResultBatching policy, size_t max_bytes, Send send)
    : policy_(policy), max_bytes_(max_bytes), send_(std::move(send)), thread_([this] { linger_loop(); }) {}

ResultBatcher::~ResultBatcher() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
  flush();
}

void ResultBatcher::add(v1::TileResult&& result, int request_more, bool nothing_else_to_render) {
  std::optional<v1::WorkerMessage> before, now;
  bool started = false;
  {
    std::lock_guard lock(mu_);
    const size_t bytes = result.ByteSizeLong();
    // A result that would push the batch over the byte bound starts the next batch.
    if (pending_.results().results_size() > 0 && pending_bytes_ + bytes > max_bytes_) before = take_locked();
    v1::TileResults* batch = pending_.mutable_results();
    started = batch->results_size() == 0;
    if (started) oldest_ = std::chrono::steady_clock::now();
    *batch->add_results() = std::move(result);
    batch->set_request_more(batch->request_more() + std::max(0, request_more));
    pending_bytes_ += bytes;
    const bool full = size_t(batch->results_size()) >= policy_.max_tiles || pending_bytes_ >= max_bytes_;
    if (full || nothing_else_to_render || policy_.linger.count() <= 0) {
      now = take_locked();
      started = false;
    }
  }
  if (started) cv_.notify_one();  // the linger thread starts counting
  send(std::move(before));
  send(std::move(now));
}

void ResultBatcher::flush() {
  std::optional<v1::WorkerMessage> out;
  {
    std::lock_guard lock(mu_);
    out = take_locked();
  }
  send(std::move(out));
}

ResultBatcher::Counts ResultBatcher::counts() const {
  std::lock_guard lock(mu_);
  return counts_;
}

std::optional<v1::WorkerMessage> ResultBatcher::take_locked() {
  if (pending_.results().results_size() == 0) return std::nullopt;
  std::optional<v1::WorkerMessage> out(std::move(pending_));
  pending_.Clear();
  pending_bytes_ = 0;
  ++counts_.messages;
  counts_.results += out->results().results_size();
  return out;
}

void ResultBatcher::send(std::optional<v1::WorkerMessage> m) {
  if (m) send_(*m);
}

void ResultBatcher::linger_loop() {
  std::unique_lock lock(mu_);
  while (!stop_) {
    if (pending_.results().results_size() == 0) {
      cv_.wait(lock);
      continue;
    }
    const auto due = oldest_ + policy_.linger;
    if (std::chrono::steady_clock::now() < due) {
      cv_.wait_until(lock, due);
      continue;
    }
    std::optional<v1::WorkerMessage> out = take_locked();
    lock.unlock();
    send(std::move(out));
    lock.lock();
  }
}

}  // namespace tessera::worker

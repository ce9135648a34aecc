// SPDX-License-Identifier: Apache-2.0
// Gathers a session's finished tiles into TileResults messages, by the rules of
// farm/result_batching.h: a batch goes when it is full, when the worker has nothing left to
// render, or when its oldest result has waited the linger (the batcher's own thread watches
// that). Each batch carries the tiles the worker asks for with it.
//
// The render threads call add(); sending goes through `send` (the session's serialized write),
// never under the batcher's lock, so a slow network holds up no render thread that is not itself
// sending.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

#include "farm/result_batching.h"
#include "tessera/v1/worker_service.pb.h"

namespace tessera::worker {

class ResultBatcher {
 public:
  // Writes one message to the coordinator; false once the stream is gone.
  using Send = std::function<bool(const tessera::v1::WorkerMessage&)>;

  ResultBatcher(farm::ResultBatching policy, size_t max_bytes, Send send);
  ~ResultBatcher();  // sends what waits, then stops the thread
  ResultBatcher(const ResultBatcher&) = delete;
  ResultBatcher& operator=(const ResultBatcher&) = delete;

  // A finished tile (moved in) and the tiles to ask for with it. `nothing_else_to_render`: no
  // tile is waiting to start on this worker, so waiting for company would only delay the
  // worker's next request: the batch goes now.
  void add(tessera::v1::TileResult&& result, int request_more, bool nothing_else_to_render);
  // Sends whatever waits (leaving: the last results must not sit out a linger).
  void flush();

  // Messages and results sent so far (the worker logs them when it leaves).
  struct Counts {
    int64_t messages = 0;
    int64_t results = 0;
  };
  Counts counts() const;

 private:
  // Takes the waiting batch out under mu_ (empty optional: nothing waits).
  std::optional<tessera::v1::WorkerMessage> take_locked();
  void send(std::optional<tessera::v1::WorkerMessage> m);
  void linger_loop();

  const farm::ResultBatching policy_;
  const size_t max_bytes_;
  const Send send_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  tessera::v1::WorkerMessage pending_;  // its `results`, being filled
  size_t pending_bytes_ = 0;
  std::chrono::steady_clock::time_point oldest_;  // when the first waiting result came
  Counts counts_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace tessera::worker

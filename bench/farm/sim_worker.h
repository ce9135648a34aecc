// SPDX-License-Identifier: Apache-2.0
// A simulated tessera-worker for the coordinator load generator: it speaks worker_service.proto
// as worker/connection.cpp does (register; pull as many tiles as farm::ResultBatching::depth says
// for its tile time, then one more per finished tile, asked for with the results; results
// gathered into batches as farm/result_batching.h says; a heartbeat every interval the welcome
// names; revoked leases are not returned; a span lease's tiles each come back as a result of
// their own) but, instead of rendering, returns a constant tile of the leased size after a fixed
// delay. It runs on the gRPC callback API, so a thousand of them share gRPC's few
// threads and one timer thread instead of a thousand OS threads.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <queue>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "farm/result_batching.h"
#include "tessera/v1/worker_service.grpc.pb.h"

namespace tessera::bench {

using SteadyClock = std::chrono::steady_clock;

// Runs delayed tile results and heartbeats for every simulated worker on one thread.
class SimTimer {
 public:
  SimTimer();
  ~SimTimer();
  SimTimer(const SimTimer&) = delete;
  SimTimer& operator=(const SimTimer&) = delete;
  void at(SteadyClock::time_point when, std::function<void()> f);
  // Drops every pending callback and joins the thread: call before destroying the workers.
  void stop();

 private:
  struct Entry {
    SteadyClock::time_point when;
    uint64_t seq;
    std::function<void()> f;
    bool operator>(const Entry& o) const { return std::tie(when, seq) > std::tie(o.when, o.seq); }
  };
  void loop();
  std::mutex mu_;
  std::condition_variable cv_;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> q_;
  uint64_t seq_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

struct SimOptions {
  int threads = 1;                       // reported at registration
  std::chrono::microseconds delay{0};    // "render time" of every tile
  // As tessera-worker: batches of results and assignments where the coordinator reads them, the
  // pull depth from the tile time. Off: one result a message, one assignment a message, a pull
  // depth of 2 x threads (the protocol before batches).
  bool batches = true;
  // As tessera-worker: span leases (Register.reads_spans), one result a tile. Off: single-tile
  // leases only (the protocol before spans).
  bool spans = true;
  farm::ResultBatching batching;
};

struct SimCounters {
  std::atomic<int64_t> assignments{0};      // leases
  std::atomic<int64_t> assigned_tiles{0};   // their tiles (more than the leases where spans come)
  std::atomic<int64_t> refused{0};          // span leases refused as malformed (a RenderFailed each)
  std::atomic<int64_t> results{0};
  std::atomic<int64_t> result_messages{0};  // messages that carried results
  std::atomic<int64_t> revoked{0};       // revocations of a tile still "rendering" here
  std::atomic<int64_t> heartbeats{0};
  std::atomic<int64_t> bytes_out{0};     // serialized WorkerMessage bytes sent
  std::atomic<int64_t> bytes_in{0};      // serialized CoordinatorMessage bytes received
};

class SimWorker : public grpc::ClientBidiReactor<tessera::v1::WorkerMessage, tessera::v1::CoordinatorMessage> {
 public:
  SimWorker(tessera::v1::WorkerService::Stub* stub, std::string name, SimOptions options, SimTimer& timer,
            SimCounters& counters);
  // Opens the session and registers. welcomed() turns true when the coordinator answers.
  void start();
  bool welcomed() const { return welcomed_.load(); }
  // The first pull. Kept apart from start() so that the benchmark can connect every worker, then
  // queue a job, then let them all loose.
  void go();
  // Cancels the session; wait_done() returns once gRPC has finished with this reactor.
  void stop();
  bool wait_done(SteadyClock::time_point deadline);
  bool ended_early() const { return ended_early_.load(); }  // the stream ended before stop()
  const grpc::Status& status() const { return status_; }

 private:
  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnDone(const grpc::Status& s) override;

  void send(tessera::v1::WorkerMessage m);
  void request(int count);
  void assigned(const tessera::v1::Assignment& a, bool more_in_message);
  // The one tile of `a` (a single-tile lease, or one tile cut from a span) is "rendered".
  void finish_tile(const tessera::v1::Assignment& a, bool more_coming);
  // Sends the waiting batch if it is still generation `gen` (the linger timer's call).
  void flush_batch(uint64_t gen);
  // Sends the waiting batch; `lock` holds mu_ and is released.
  void send_batch(std::unique_lock<std::mutex>& lock);
  void heartbeat();
  void release_hold_locked(bool* release);

  tessera::v1::WorkerService::Stub* stub_;
  std::string name_;
  SimOptions options_;
  SimTimer& timer_;
  SimCounters& counters_;
  grpc::ClientContext ctx_;
  tessera::v1::CoordinatorMessage in_;
  std::chrono::milliseconds heartbeat_interval_{1000};

  std::mutex mu_;  // guards everything below
  std::deque<tessera::v1::WorkerMessage> queue_;
  tessera::v1::WorkerMessage current_;  // the one write in flight
  bool writing_ = false;
  SteadyClock::time_point last_send_ = SteadyClock::now();  // a heartbeat goes only after an interval without one
  bool stopped_ = false;        // no more writes
  bool hold_released_ = false;
  // Tiles (lease id, tile index) "rendering" (waiting on the timer), and those of them revoked.
  std::set<std::pair<uint64_t, int>> pending_;
  std::set<std::pair<uint64_t, int>> revoked_;
  tessera::v1::WorkerMessage batch_;  // results waiting for company
  uint64_t batch_gen_ = 0;            // bumped each time a batch is sent

  std::atomic<bool> welcomed_{false};
  std::atomic<bool> result_requests_{false};  // the welcome said TileResult.request_more is read
  std::atomic<bool> result_batches_{false};   // the welcome said TileResults is read (and batches on)
  std::atomic<bool> ended_early_{false};
  std::mutex done_mu_;
  std::condition_variable done_cv_;
  bool done_ = false;
  grpc::Status status_;
};

}  // namespace tessera::bench

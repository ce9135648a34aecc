// SPDX-License-Identifier: Apache-2.0
// The worker's life: connect to the coordinator, register, pull tiles, render them on the pool,
// stream results back; on a lost connection, reconnect with exponential backoff (with jitter, so
// a restarted coordinator is not hit by every worker at the same instant). request_stop()
// leaves cleanly: unstarted tiles are returned, running ones finished and sent. With
// `exit_when_idle`, the worker leaves that way by itself once it has held no tile for that long.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "farm/bundle_cache.h"
#include "farm/channel.h"
#include "farm/result_batching.h"
#include "render_pool.h"
#include "tessera/v1/worker_service.grpc.pb.h"

namespace tessera::worker {

struct WorkerOptions {
  std::string coordinator = farm::kDefaultCoordinator;
  std::string name;
  int threads = 1;
  std::filesystem::path cache_dir;
  int extra_delay_ms = 0;  // testing only: sleep after each tile so jobs last long enough
  farm::ChannelSecurity security;  // TLS and the worker token (farm/channel.h)
  // Testing only: corrupt every result this way, so the coordinator's refusal and blocklist can
  // be tested with real processes: "nan" (a NaN pixel), "wrong-size" (rgb one pixel short),
  // "stale" (a lease id never issued), "no-scene" (report the scene as unloadable).
  std::string test_fault;
  // How results are gathered into messages, and so how many tiles the worker keeps on hand.
  farm::ResultBatching batching;
  // Leave (as on SIGTERM) once no tile has been on hand for this long, connected or not: a batch
  // allocation or a Kubernetes Job then ends with the farm's queue. Zero: never.
  std::chrono::milliseconds exit_when_idle{0};
  std::chrono::milliseconds backoff_initial{200};
  std::chrono::milliseconds backoff_max{10000};
};

class WorkerConnection {
 public:
  explicit WorkerConnection(WorkerOptions options);
  ~WorkerConnection();
  // Runs sessions until request_stop() (or, with exit_when_idle, until idle that long). Returns
  // the process exit code.
  int run();
  // Thread-safe; called from the signal thread.
  void request_stop();

 private:
  struct Session;
  // One connected session; returns true if the coordinator accepted us (resets the backoff).
  bool run_session();
  void handle_assignment(const std::shared_ptr<Session>& s, const tessera::v1::Assignment& a);
  // Renders one tile of a lease (`span`: of a span lease) and hands on its result.
  void render(const std::shared_ptr<Session>& s, const tessera::v1::Assignment& a, bool span);
  // Answers a span lease split_span refuses with a RenderFailed for it.
  void refuse_span(const std::shared_ptr<Session>& s, const tessera::v1::Assignment& a, const std::string& problem);
  void inject_test_fault(tessera::v1::TileResult* r) const;  // --test-fault
  std::string fetch_bundle(const std::string& sha256);
  void sleep_backoff(std::chrono::milliseconds d);
  // --exit-when-idle: watches the render pool and calls request_stop() once it has been empty
  // for options_.exit_when_idle; returns when that happened or stop_ was set otherwise.
  void watch_idle();

  WorkerOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<tessera::v1::WorkerService::Stub> stub_;
  farm::BundleCache cache_;
  RenderPool pool_;
  std::atomic<bool> stop_{false};
  std::mutex mu_;                      // guards current_ and the backoff wait
  std::condition_variable cv_;
  std::shared_ptr<Session> current_;
};

}  // namespace tessera::worker

// SPDX-License-Identifier: Apache-2.0
// The coordinator's Prometheus metrics, served as text by GET /metrics on the HTTP
// listener (server/monitor/http_listener.h). Names follow Prometheus conventions: `tessera_`
// prefix, base units (seconds, bytes), `_total` on counters.
//
// Two kinds of sources:
//   - events (tiles completed, rays, leases expired, speculative copies, faults, store batches):
//     counted as they happen, as a scheduler observer (FarmView::add_observer). Each event
//     costs an atomic add or a histogram bucket, under the coordinator's mutex;
//   - levels (jobs by state, tiles queued / leased / done, work left, workers, ray servers, watch
//     backlog): read from a FarmView::snapshot() when Prometheus scrapes, so they cost nothing
//     in between.
//
// tessera_work_seconds is the level an autoscaler sizes the workers by (docker/k8s/keda): the
// render-thread seconds the tiles not yet done need, queued or leased, estimated per job as its
// tiles times its own mean tile time so far; a job with no tile done yet is counted at the mean
// tile time of every tile finished since the coordinator started, and before any tile finished at
// a nominal second a tile, so that a scaler at zero workers sees a new job at all.
//
// Labels stay bounded: job states and tile states are fixed sets, workers are counted per
// Embree ISA (a handful of values). No label carries a job id or a worker name: those grow
// without bound on a long-lived farm (one time series each, forever, in Prometheus).
#pragma once

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <mutex>
#include <set>
#include <string>

#include "farm_view.h"

namespace tessera::server {

class FarmMetrics : public SchedulerListener {
 public:
  // Registers itself as an observer of `coordinator`, which must outlive it. Call before any
  // stream starts. It unregisters when destroyed, so no event reaches it afterwards.
  explicit FarmMetrics(FarmView& coordinator);
  ~FarmMetrics() override;
  FarmMetrics(const FarmMetrics&) = delete;
  FarmMetrics& operator=(const FarmMetrics&) = delete;

  // The Prometheus text exposition format (version 0.0.4) of every metric, levels read now.
  std::string scrape();

  // One batch of the job store's writes made durable, in `seconds`, with `bytes` of tiles: the
  // store's batch observer (JobStore::set_batch_observer), set by whoever holds both.
  void store_batch(double seconds, uint64_t bytes);

  // SchedulerListener (under the coordinator's mutex).
  void tile_leased(const Assignment& a) override;
  void lease_ended(const Lease& lease, LeaseEnd why) override;
  void tile_finished(const TileKey&, const TileOutput& out, WorkerId) override;
  void worker_faulted(const JobId&, const WorkerStats&, std::string_view, int, bool blocklisted) override;

 private:
  // Counters that mirror a running total kept elsewhere (bundle bytes, store failures).
  static void advance(prometheus::Counter& c, double total) {
    if (total > c.Value()) c.Increment(total - c.Value());
  }

  FarmView& coordinator_;
  prometheus::Registry registry_;
  // Events.
  prometheus::Counter& tiles_completed_;
  prometheus::Counter& rays_;
  prometheus::Histogram& tile_seconds_;
  prometheus::Counter& leases_issued_;
  prometheus::Counter& tiles_leased_;
  prometheus::Counter& lease_expiries_;
  prometheus::Counter& speculative_copies_;
  prometheus::Counter& lost_races_;
  prometheus::Counter& faults_;
  prometheus::Counter& blocklistings_;
  prometheus::Histogram& store_write_seconds_;
  prometheus::Counter& store_bytes_;
  prometheus::Counter& store_failures_;
  prometheus::Counter& bundle_stored_bytes_;
  prometheus::Counter& bundle_served_bytes_;
  // Levels, set at each scrape.
  prometheus::Family<prometheus::Gauge>& jobs_;
  prometheus::Family<prometheus::Gauge>& tiles_;
  prometheus::Family<prometheus::Gauge>& workers_;
  std::set<prometheus::Gauge*> workers_isa_seen_;
  prometheus::Gauge& watch_backlog_;
  prometheus::Gauge& undelivered_frames_;
  prometheus::Gauge& undelivered_bytes_;
  prometheus::Gauge& undelivered_oldest_;
  prometheus::Gauge& store_queued_;
  prometheus::Gauge& ray_servers_;
  prometheus::Family<prometheus::Gauge>& work_;
  std::mutex scrape_mu_;  // one scrape at a time sets the levels
};

}  // namespace tessera::server

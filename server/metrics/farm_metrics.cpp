// SPDX-License-Identifier: Apache-2.0
#include "farm_metrics.h"

#include <prometheus/text_serializer.h>

#include <algorithm>
#include <map>

namespace tessera::server {

namespace {

using prometheus::BuildCounter;
using prometheus::BuildGauge;
using prometheus::BuildHistogram;

prometheus::Counter& counter(prometheus::Registry& r, const char* name, const char* help) {
  return BuildCounter().Name(name).Help(help).Register(r).Add({});
}

prometheus::Histogram& histogram(prometheus::Registry& r, const char* name, const char* help,
                                 const prometheus::Histogram::BucketBoundaries& buckets) {
  return BuildHistogram().Name(name).Help(help).Register(r).Add({}, buckets);
}

prometheus::Family<prometheus::Gauge>& gauges(prometheus::Registry& r, const char* name, const char* help) {
  return BuildGauge().Name(name).Help(help).Register(r);
}

// Powers of two from `lo`: a tile takes milliseconds to minutes, a store batch a fraction of a
// millisecond (tmpfs) to seconds (a slow disk's fsync).
prometheus::Histogram::BucketBoundaries powers_of_two(double lo, int n) {
  prometheus::Histogram::BucketBoundaries b;
  for (int i = 0; i < n; ++i) b.push_back(lo * double(1u << i));
  return b;
}

}  // namespace

FarmMetrics::FarmMetrics(FarmView& coordinator)
    : coordinator_(coordinator),
      tiles_completed_(counter(registry_, "tessera_tiles_completed_total", "Tiles whose result was accepted")),
      rays_(counter(registry_, "tessera_rays_traced_total",
                    "Rays traced for accepted tiles (camera, shadow and secondary)")),
      tile_seconds_(histogram(registry_, "tessera_tile_render_seconds",
                              "Wall time a worker spent rendering an accepted tile", powers_of_two(0.001, 17))),
      leases_issued_(counter(registry_, "tessera_leases_issued_total",
                             "Leases handed to workers (a lease is a span of one or more tiles of a frame)")),
      tiles_leased_(counter(registry_, "tessera_tiles_leased_total",
                            "Tiles handed to workers in leases (over tessera_leases_issued_total: tiles a lease)")),
      lease_expiries_(counter(registry_, "tessera_lease_expiries_total",
                              "Leases whose worker went silent past the lease timeout (tile requeued)")),
      speculative_copies_(counter(registry_, "tessera_speculative_copies_total",
                                  "Second copies of in-flight tiles handed to idle workers")),
      lost_races_(counter(registry_, "tessera_speculative_lost_races_total",
                          "Leases revoked because another copy of their tile finished first")),
      faults_(counter(registry_, "tessera_worker_faults_total",
                      "Bad results and render failures reported against workers")),
      blocklistings_(counter(registry_, "tessera_worker_blocklistings_total",
                             "Times a worker was blocklisted for a job after too many faults")),
      store_write_seconds_(histogram(registry_, "tessera_store_write_seconds",
                                     "Time to make one batch of writes durable (tile segment, fsyncs, SQLite commit)",
                                     powers_of_two(0.0001, 16))),
      store_bytes_(counter(registry_, "tessera_store_written_bytes_total", "Tile bytes written to the tile store")),
      store_failures_(counter(registry_, "tessera_store_write_failures_total",
                              "Store batches that failed (full disk, I/O error) and are retried")),
      bundle_stored_bytes_(counter(registry_, "tessera_bundle_stored_bytes_total",
                                   "Bytes of new scene bundles stored by the coordinator")),
      bundle_served_bytes_(counter(registry_, "tessera_bundle_served_bytes_total",
                                   "Bytes of scene bundles sent to workers")),
      jobs_(gauges(registry_, "tessera_jobs", "Jobs in the coordinator's memory, by state")),
      tiles_(gauges(registry_, "tessera_tiles",
                    "Tiles of the jobs in memory: queued (waiting for a worker), leased (being rendered), done")),
      workers_(gauges(registry_, "tessera_workers_connected", "Workers connected, by the Embree ISA their kernels use")),
      watch_backlog_(gauges(registry_, "tessera_watch_backlog_messages",
                            "Messages queued for clients' watch streams and not yet sent")
                         .Add({})),
      undelivered_frames_(gauges(registry_, "tessera_undelivered_frames",
                                 "Finished frames of jobs with a recorded output that no client has delivered yet "
                                 "(kept past retention; docs/farm.md, Delivery)")
                              .Add({})),
      undelivered_bytes_(gauges(registry_, "tessera_undelivered_bytes",
                                "Encoded tile bytes of the undelivered frames (new jobs are refused at "
                                "tessera-server --max-undelivered-gb)")
                             .Add({})),
      undelivered_oldest_(gauges(registry_, "tessera_undelivered_oldest_seconds",
                                 "Seconds since the oldest undelivered frame finished (0 when none)")
                              .Add({})),
      store_queued_(gauges(registry_, "tessera_store_queued_writes", "Writes waiting for the store's next batch").Add({})),
      ray_servers_(gauges(registry_, "tessera_ray_servers",
                          "Ray servers (tessera-rays) announced to the coordinator and not expired")
                       .Add({})),
      work_(gauges(registry_, "tessera_work_seconds",
                   "Render-thread seconds the tiles not yet done need, by state (queued: waiting for a worker; "
                   "leased: being rendered): each job's tiles times its mean tile time so far, else the mean of "
                   "every tile finished since start, else 1 s a tile")) {
  coordinator.add_observer(this);
  // Every state is exported from the first scrape on, at 0 when empty, so a query for one
  // never finds nothing.
  for (JobState s : {JobState::kQueued, JobState::kRunning, JobState::kDone, JobState::kCancelled, JobState::kFailed}) {
    jobs_.Add({{"state", job_state_name(s)}});
  }
  for (const char* s : {"queued", "leased", "done"}) tiles_.Add({{"state", s}});
  for (const char* s : {"queued", "leased"}) work_.Add({{"state", s}});
}

FarmMetrics::~FarmMetrics() {
  coordinator_.remove_observer(this);
}

void FarmMetrics::tile_leased(const Assignment& a) {
  leases_issued_.Increment();
  tiles_leased_.Increment(a.lease.count);
  if (a.lease.speculative) speculative_copies_.Increment();
}

void FarmMetrics::lease_ended(const Lease&, LeaseEnd why) {
  if (why == LeaseEnd::kExpired) lease_expiries_.Increment();
  if (why == LeaseEnd::kLostRace) lost_races_.Increment();
}

void FarmMetrics::tile_finished(const TileKey&, const TileOutput& out, WorkerId) {
  tiles_completed_.Increment();
  rays_.Increment(double(out.rays));
  tile_seconds_.Observe(out.seconds);
}

void FarmMetrics::worker_faulted(const JobId&, const WorkerStats&, std::string_view, int, bool blocklisted) {
  faults_.Increment();
  if (blocklisted) blocklistings_.Increment();
}

void FarmMetrics::store_batch(double seconds, uint64_t bytes) {
  store_write_seconds_.Observe(seconds);
  store_bytes_.Increment(double(bytes));
}

std::string FarmMetrics::scrape() {
  const FarmSnapshot f = coordinator_.snapshot();
  std::lock_guard lock(scrape_mu_);
  std::map<std::string, double> by_state;
  double leased = 0, done = 0;
  for (const JobSnapshot& j : f.jobs) {
    by_state[job_state_name(j.state)] += 1;
    leased += double(j.tiles_leased);
    done += double(j.tiles_done);
  }
  for (JobState s : {JobState::kQueued, JobState::kRunning, JobState::kDone, JobState::kCancelled, JobState::kFailed}) {
    jobs_.Add({{"state", job_state_name(s)}}).Set(by_state[job_state_name(s)]);
  }
  tiles_.Add({{"state", "queued"}}).Set(double(f.tiles_queued));
  tiles_.Add({{"state", "leased"}}).Set(leased);
  tiles_.Add({{"state", "done"}}).Set(done);
  // Work left (the header says how it is estimated). Every tile finished since start is in the
  // render-time histogram: its sum over its count is the mean for jobs with no tile timed yet.
  const auto timed = tile_seconds_.Collect().histogram;
  const double untimed_mean = timed.sample_count > 0 ? timed.sample_sum / double(timed.sample_count) : 1.0;
  double work_queued = 0, work_leased = 0;
  for (const JobSnapshot& j : f.jobs) {
    if (job_ended(j.state)) continue;
    const double mean = j.tiles_done > 0 ? j.tile_seconds / double(j.tiles_done) : untimed_mean;
    work_leased += double(j.tiles_leased) * mean;
    work_queued += double(std::max<int64_t>(0, j.tiles_total - j.tiles_done - j.tiles_leased)) * mean;
  }
  work_.Add({{"state", "queued"}}).Set(work_queued);
  work_.Add({{"state", "leased"}}).Set(work_leased);
  // ISAs seen since start keep their series (at 0 once their workers left): a series that
  // vanishes reads as "no data" rather than "no workers".
  std::map<std::string, double> by_isa;
  for (const WorkerStats& w : f.workers) by_isa[w.info.embree_isa] += 1;
  for (auto* g : workers_isa_seen_) g->Set(0);
  for (const auto& [isa, n] : by_isa) {
    auto& g = workers_.Add({{"isa", isa.empty() ? "unknown" : isa}});
    workers_isa_seen_.insert(&g);
    g.Set(n);
  }
  watch_backlog_.Set(double(f.watch_backlog));
  undelivered_frames_.Set(double(f.delivery.frames()));
  undelivered_bytes_.Set(double(f.delivery.bytes()));
  undelivered_oldest_.Set(f.delivery.oldest_seconds());
  store_queued_.Set(double(f.store.queued));
  ray_servers_.Set(double(coordinator_.live_ray_servers()));
  advance(store_failures_, double(f.store.failures));
  advance(bundle_stored_bytes_, double(coordinator_.bundle_bytes_stored()));
  advance(bundle_served_bytes_, double(coordinator_.bundle_bytes_served()));
  return prometheus::TextSerializer().Serialize(registry_.Collect());
}

}  // namespace tessera::server

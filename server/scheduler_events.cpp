// SPDX-License-Identifier: Apache-2.0
// The coordinator as the scheduler's listener. Every event runs under the coordinator's mutex: it
// first tells the observers (metrics, web monitor), then persists the change in the job store,
// logs it and queues what the streams must hear (status and tiles to watchers, revocations and
// goodbyes to workers). Nothing here writes to a stream: locked() pumps the touched outboxes once
// the mutex is released.
#include "coordinator.h"

#include <spdlog/spdlog.h>

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

void Coordinator::job_submitted(const JobSnapshot& s) {
  notify([&](SchedulerListener& o) { o.job_submitted(s); });

  if (jobs_store_) jobs_store_->job_submitted(s);
  awaiting_first_tile_[s.id] = s.submitted;
  spdlog::info("job {} submitted: '{}', frames {}-{}, {}x{} {} spp, {} tiles of {} px, priority {}", s.id,
               s.spec.name, s.spec.first_frame, s.spec.last_frame, s.spec.width, s.spec.height, s.spec.spp,
               s.tiles_total, s.spec.tile_size, s.spec.priority);
}

void Coordinator::job_state_changed(const JobId& id, JobState state) {
  notify([&](SchedulerListener& o) { o.job_state_changed(id, state); });

  auto s = scheduler_.job(id);
  if (jobs_store_) jobs_store_->job_updated(*s);
  if (job_ended(state)) {
    ended_[id] = s->ended.value_or(Clock::now());
    awaiting_first_tile_.erase(id);
    passes_.forget(id);
  }
  if (state == JobState::kFailed) {
    spdlog::error("job {} failed: {}", id, s->error);
  } else if (state == JobState::kDone) {
    spdlog::info("job {} done in {:.2f} s: {} tiles, {:.1f} Mrays, {} duplicate results discarded", id,
                 std::chrono::duration<double>(*s->ended - s->submitted).count(), s->tiles_done, s->rays / 1e6,
                 s->duplicates_discarded);
  } else {
    spdlog::info("job {} {}", id, job_state_name(state));
  }
  if (job_ended(state)) finish_watchers_locked(id, false);  // deliverers stay for what is undelivered
}

void Coordinator::job_priority_changed(const JobId& id, int priority) {
  notify([&](SchedulerListener& o) { o.job_priority_changed(id, priority); });
  if (jobs_store_) jobs_store_->job_updated(*scheduler_.job(id));
  spdlog::info("job {} priority set to {}", id, priority);
}

void Coordinator::tile_leased(const Assignment& a) {
  notify([&](SchedulerListener& o) { o.tile_leased(a); });

  if (jobs_store_) jobs_store_->lease_issued(a.lease, std::to_string(a.lease.worker));
  spdlog::debug("lease {} job {} frame {} tile {}{} to worker {}{}", a.lease.id, a.lease.tile.job, a.lease.tile.frame,
                a.lease.tile.tile, a.lease.count > 1 ? fmt::format("-{}", a.lease.tile.tile + a.lease.count - 1) : "",
                a.lease.worker, a.lease.speculative ? " (speculative copy)" : "");
}

void Coordinator::lease_ended(const Lease& lease, LeaseEnd why) {
  notify([&](SchedulerListener& o) { o.lease_ended(lease, why); });

  if (jobs_store_) jobs_store_->lease_ended(lease.id);
  if (why == LeaseEnd::kStalled) {
    peer_warnings_.warn(lease.worker, "worker {} returned nothing for longer than the stall limit: its leases are "
                                      "requeued (lease {}, job {} frame {} tile {})",
                        lease.worker, lease.id, lease.tile.job, lease.tile.frame, lease.tile.tile);
  }
  if (why != LeaseEnd::kLostRace && why != LeaseEnd::kCancelled && why != LeaseEnd::kBlocklisted &&
      why != LeaseEnd::kStalled) {
    return;
  }
  auto it = workers_.find(lease.worker);
  if (it == workers_.end()) return;
  v1::CoordinatorMessage m;
  m.mutable_revoke()->add_lease_ids(lease.id);
  it->second.sink->push(std::move(m));
  touched_workers_.push_back(it->second.sink);
}

void Coordinator::span_tile_lost(const Lease& lease, int tile) {
  notify([&](SchedulerListener& o) { o.span_tile_lost(lease, tile); });

  auto it = workers_.find(lease.worker);
  if (it == workers_.end()) return;
  v1::CoordinatorMessage m;
  v1::LeaseTile* t = m.mutable_revoke()->add_tiles();
  t->set_lease_id(lease.id);
  t->set_tile_index(tile);
  it->second.sink->push(std::move(m));
  touched_workers_.push_back(it->second.sink);
}

void Coordinator::tile_finished(const TileKey& key, const TileOutput& out, WorkerId worker) {
  notify([&](SchedulerListener& o) { o.tile_finished(key, out, worker); });

  if (jobs_store_) jobs_store_->tile_done(key, out);
  if (auto it = awaiting_first_tile_.find(key.job); it != awaiting_first_tile_.end()) {
    spdlog::info("job {} first tile {:.3f} s after submit", key.job,
                 std::chrono::duration<double>(Clock::now() - it->second).count());
    awaiting_first_tile_.erase(it);
  }
  route_tile_locked(key, out);
}

void Coordinator::frame_finished(const JobId& id, int frame) {
  notify([&](SchedulerListener& o) { o.frame_finished(id, frame); });

  spdlog::info("job {} frame {} finished", id, frame);
  frame_undelivered_locked(id, frame, Clock::now());
  route_frame_done_locked(id, frame);
}

void Coordinator::frame_acknowledged(const JobId& id, int frame) {
  notify([&](SchedulerListener& o) { o.frame_acknowledged(id, frame); });

  if (jobs_store_) {
    if (const int n = scheduler_.tiles_per_frame(id)) jobs_store_->frame_acknowledged(id, frame, n);
  }
  spdlog::info("job {} frame {} delivered to the client; its tiles are released", id, frame);
  deliveries_.acknowledged(id, frame);
  undelivered_.remove(id, frame);  // the job's last one: ack_frame evicts the job, ending its streams
}

void Coordinator::worker_joined(const WorkerStats& w) {
  notify([&](SchedulerListener& o) { o.worker_joined(w); });

  spdlog::info("worker {} '{}' joined from {}: {} threads, Embree {}", w.id, w.info.name, w.info.peer,
               w.info.threads, w.info.embree_isa);
  if (!isas_.empty() && !isas_.count(w.info.embree_isa)) {
    spdlog::warn("worker {} '{}' runs Embree {} kernels, other workers ran {}: tiles may differ in the last bits",
                 w.id, w.info.name, w.info.embree_isa, *isas_.begin());
  }
  isas_.insert(w.info.embree_isa);
}

void Coordinator::worker_left(const WorkerStats& w, std::string_view reason) {
  notify([&](SchedulerListener& o) { o.worker_left(w, reason); });

  spdlog::info("worker {} '{}' left ({}): {} tiles rendered, {} tiles requeued", w.id, w.info.name, reason,
               w.tiles_done, w.in_flight);
  peer_warnings_.forget(w.id);
  auto it = workers_.find(w.id);
  if (it == workers_.end()) return;
  it->second.sink->finish(Status(StatusCode::UNAVAILABLE, "coordinator dropped this worker: " + std::string(reason)));
  touched_workers_.push_back(it->second.sink);
  workers_.erase(it);
}

void Coordinator::worker_faulted(const JobId& job, const WorkerStats& w, std::string_view reason, int faults,
                                 bool blocklisted) {
  notify([&](SchedulerListener& o) { o.worker_faulted(job, w, reason, faults, blocklisted); });

  spdlog::warn("worker {} '{}': refused result for job {}: {} (fault {} of {} for this job)", w.id, w.info.name, job,
               reason, faults, scheduler_.options().max_faults);
  if (blocklisted) {
    spdlog::error("worker {} '{}' is blocklisted for job {} after {} faults: it gets no more of its tiles", w.id,
                  w.info.name, job, faults);
    if (jobs_store_) jobs_store_->worker_blocklisted(job, w.info.name);  // survives a restart
  }
}

}  // namespace tessera::server

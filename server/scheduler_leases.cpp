// SPDX-License-Identifier: Apache-2.0
// The scheduler's leases: a lease is a span of consecutive tiles of one frame (docs/farm.md,
// "Lease rules"), each of whose tiles finishes, goes back or loses a race to a speculative copy on
// its own; the count of tiles with a single copy in flight that speculation picks from.
#include "scheduler.h"

#include <algorithm>

namespace tessera::server {

void Scheduler::set_single_copy(Job& job, LeaseId lease, bool single) {
  if (single) {
    if (job.single_copies.insert(lease).second && job.single_copies.size() == 1) speculable_.insert(job.id);
  } else if (job.single_copies.erase(lease) && job.single_copies.empty()) {
    speculable_.erase(job.id);
  }
}

std::optional<Assignment> Scheduler::speculate_for(Worker& w) {
  // The oldest lease with a pending tile that has a single copy in flight, held by someone else:
  // if its worker is slow or dying, the second copy finishes the job sooner. Each job keeps its
  // candidates ordered by lease id (age), so this looks at the first few of each running job
  // (skipping only this worker's own) instead of every lease.
  const Lease* best = nullptr;
  for (const JobId& id : speculable_) {
    const Job& job = *find_job(id);
    if (job.held || job.state != JobState::kRunning || blocked(job, w)) continue;
    for (LeaseId lid : job.single_copies) {
      if (best && lid > best->id) break;
      const Lease& lease = leases_.at(lid);
      if (lease.worker == w.stats.id) continue;
      best = &lease;
      break;
    }
  }
  if (!best) return std::nullopt;
  Job& job = *find_job(best->tile.job);
  const int fi = best->tile.frame - job.spec.first_frame;
  const Frame& frame = job.frames[size_t(fi)];
  // One tile of it: the last such of a span, the one its worker reaches last.
  for (int t = best->tile.tile + best->count - 1; t >= best->tile.tile; --t) {
    const Tile& tile = frame.tiles[size_t(t)];
    if (best->is_pending(t) && tile.state == TileState::kLeased && tile.leases.size() == 1) {
      return issue(w, job, Span{fi, t, 1}, true);
    }
  }
  return std::nullopt;  // not reached: single_copies holds only leases with such a tile
}

template <typename F>
void Scheduler::copies_changed(Job& job, Tile& tile, F&& change) {
  if (tile.state == TileState::kLeased && tile.leases.size() == 1) count_single(job, tile.leases.front(), -1);
  change();
  if (tile.state == TileState::kLeased && tile.leases.size() == 1) count_single(job, tile.leases.front(), +1);
}

void Scheduler::count_single(Job& job, LeaseId lease, int delta) {
  auto it = leases_.find(lease);
  if (it == leases_.end()) return;
  it->second.single_tiles += delta;
  set_single_copy(job, lease, it->second.single_tiles > 0);
}

Assignment Scheduler::issue(Worker& w, Job& job, const Span& span, bool speculative) {
  Frame& frame = job.frames[size_t(span.frame)];
  const TimePoint now = now_();
  Assignment a;
  a.lease.id = next_lease_++;
  a.lease.worker = w.stats.id;
  a.lease.tile = {job.id, job.spec.first_frame + span.frame, span.tile};
  a.lease.count = span.count;
  a.lease.pending = span.count >= Lease::kMaxTiles ? ~uint64_t(0) : (uint64_t(1) << span.count) - 1;
  a.lease.issued = now;
  a.lease.deadline = now + options_.lease_timeout;
  a.lease.speculative = speculative;
  a.rect = job.grid.rect(span.tile);
  a.grid = job.grid;
  a.bundle_sha256 = job.spec.bundle_sha256;
  a.overrides = job.spec.overrides;
  if (span.count == 1) a.plan = frame.tiles[size_t(span.tile)].plan;
  leases_[a.lease.id] = a.lease;
  for (int t = span.tile; t < span.tile + span.count; ++t) {
    Tile& tile = frame.tiles[size_t(t)];
    copies_changed(job, tile, [&] {
      tile.state = TileState::kLeased;
      tile.leases.push_back(a.lease.id);
    });
  }
  if (w.leases.empty()) w.last_progress = now;  // the stall clock runs while it holds work
  w.leases.insert(a.lease.id);
  w.tiles_held += span.count;
  w.stats.in_flight = int(w.tiles_held);
  w.stats.leases = int(w.leases.size());
  if (job.state == JobState::kQueued) set_state(job, JobState::kRunning);
  events().tile_leased(a);
  return a;
}

void Scheduler::drop_pending(Lease& lease, int t, bool requeue) {
  if (!lease.is_pending(t)) return;
  lease.pending &= ~(uint64_t(1) << (t - lease.tile.tile));
  if (auto wit = workers_.find(lease.worker); wit != workers_.end()) {
    --wit->second.tiles_held;
    wit->second.stats.in_flight = int(wit->second.tiles_held);
    update_wanting(wit->second);
  }
  Job& job = *find_job(lease.tile.job);
  const int fi = lease.tile.frame - job.spec.first_frame;
  Frame& frame = job.frames[size_t(fi)];
  if (frame.tiles.empty()) return;  // released: nothing to requeue
  Tile& tile = frame.tiles[size_t(t)];
  copies_changed(job, tile, [&] { std::erase(tile.leases, lease.id); });
  const bool live = job.state == JobState::kQueued || job.state == JobState::kRunning;
  if (requeue && live && tile.state == TileState::kLeased && tile.leases.empty()) {
    tile.state = TileState::kQueued;
    job.requeued.emplace_front(fi, t);  // oldest work first
    update_runnable(job);
  }
}

void Scheduler::end_lease(LeaseId id, LeaseEnd why, bool requeue) {
  auto it = leases_.find(id);
  if (it == leases_.end()) return;
  // Last tile first: each goes to the queue's front, so the span is queued again in tile order.
  for (int t = it->second.tile.tile + it->second.count - 1; t >= it->second.tile.tile; --t) {
    drop_pending(it->second, t, requeue);
  }
  const Lease lease = it->second;
  leases_.erase(it);
  if (Job* job = find_job(lease.tile.job)) set_single_copy(*job, id, false);
  if (auto wit = workers_.find(lease.worker); wit != workers_.end()) {
    wit->second.leases.erase(id);
    wit->second.stats.leases = int(wit->second.leases.size());
    update_wanting(wit->second);
  }
  events().lease_ended(lease, why);
}

Scheduler::ResultOutcome Scheduler::complete(WorkerId worker, LeaseId lease_id, int t, TileOutput output) {
  auto it = leases_.find(lease_id);
  if (it == leases_.end() || it->second.worker != worker || !it->second.is_pending(t)) {
    // Revoked, expired, foreign, or a tile of its span that another copy finished first (the
    // span was told to drop it).
    return ResultOutcome::kStaleLease;
  }
  Lease& lease = it->second;
  Job& job = *find_job(lease.tile.job);
  const int fi = lease.tile.frame - job.spec.first_frame;
  Frame& frame = job.frames[size_t(fi)];
  Tile& tile = frame.tiles[size_t(t)];
  if (auto wit = workers_.find(worker); wit != workers_.end()) {
    wit->second.stats.rays += output.rays;
    wit->second.stats.seconds += output.seconds;
    ++wit->second.results;  // more credit: drop_pending below re-evaluates its wanting
    wit->second.last_progress = now_();
  }
  if (tile.state == TileState::kDone) {  // defensive: a done tile is pending in no lease
    ++job.duplicates_discarded;
    drop_pending(lease, t, false);
    if (lease.pending == 0) end_lease(lease_id, LeaseEnd::kLostRace, false);
    return ResultOutcome::kDuplicate;
  }
  if (auto wit = workers_.find(worker); wit != workers_.end()) ++wit->second.stats.tiles_done;
  // Taken out of the lease first (its worker's count of tiles held), then done.
  drop_pending(lease, t, false);
  copies_changed(job, tile, [&] { tile.state = TileState::kDone; });
  tile.output = std::move(output);
  ++frame.done;
  ++job.tiles_done;
  job.rays += tile.output.rays;
  job.tile_seconds += tile.output.seconds;
  slowest_tile_ = std::max(slowest_tile_, tile.output.seconds);
  const TileKey key{job.id, lease.tile.frame, t};
  if (lease.pending == 0) end_lease(lease_id, LeaseEnd::kCompleted, false);
  // First copy wins: the other copy's worker should stop wasting time on it (a whole lease of one
  // tile; just this tile of a span, whose other tiles go on).
  const std::vector<LeaseId> others = tile.leases;
  for (LeaseId other : others) {
    Lease& o = leases_.at(other);
    if (o.count > 1) {
      drop_pending(o, t, false);
      events().span_tile_lost(o, t);
    }
    if (o.pending == 0 || o.count == 1) end_lease(other, LeaseEnd::kLostRace, false);
  }
  if (job.spec.passes) {
    tile.finished_by = worker;
    if (frame.done == int(frame.tiles.size())) end_pass(job, fi);
  } else {
    events().tile_finished(key, tile.output, worker);
    if (frame.done == int(frame.tiles.size())) {
      frame.final = true;
      events().frame_finished(job.id, key.frame);
    }
  }
  if (job_ended(job.state)) return ResultOutcome::kAccepted;  // the planner failed it
  if (job.tiles_done == int64_t(job.frames.size()) * int64_t(job.grid.count())) {
    set_state(job, JobState::kDone);
  }
  return ResultOutcome::kAccepted;
}

void Scheduler::return_leases(WorkerId worker, const std::vector<LeaseId>& leases) {
  for (LeaseId lid : leases) {
    auto it = leases_.find(lid);
    if (it != leases_.end() && it->second.worker == worker) end_lease(lid, LeaseEnd::kReturned, true);
  }
}

void Scheduler::return_tiles(WorkerId worker, const std::vector<std::pair<LeaseId, int>>& tiles) {
  // Last first: each goes to the queue's front, so they go out again in the order given.
  for (auto r = tiles.rbegin(); r != tiles.rend(); ++r) {
    const auto [lid, t] = *r;
    auto it = leases_.find(lid);
    if (it == leases_.end() || it->second.worker != worker) continue;
    drop_pending(it->second, t, true);
    if (it->second.pending == 0) end_lease(lid, LeaseEnd::kReturned, true);
  }
}

}  // namespace tessera::server

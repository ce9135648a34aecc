// SPDX-License-Identifier: Apache-2.0
// The scheduler's read-only side: snapshots of jobs and workers, leases, and the finished tiles a
// client attaching may receive (Scheduler::deliverable is the one rule for those).
#include "scheduler.h"

namespace tessera::server {

JobSnapshot Scheduler::snapshot(const Job& job) const {
  JobSnapshot s;
  s.header() = job.header();
  s.tiles_per_frame = job.grid.count();
  s.tiles_total = int64_t(job.frames.size()) * s.tiles_per_frame;
  s.tiles_done = job.tiles_done;
  s.tiles_resident = job.tiles_resident;
  s.waiting_for_memory = waiting_for_memory_.count(job.id) > 0;
  s.rays = job.rays;
  s.tile_seconds = job.tile_seconds;
  s.blocklisted.assign(job.blocklisted.begin(), job.blocklisted.end());
  for (size_t f = 0; f < job.frames.size(); ++f) {
    const Frame& fr = job.frames[f];
    for (const Tile& t : fr.tiles) s.tiles_leased += t.state == TileState::kLeased;
    if (fr.final) s.frames_done.push_back(job.spec.first_frame + int(f));
    if (fr.acknowledged) s.frames_acknowledged.push_back(job.spec.first_frame + int(f));
  }
  return s;
}

std::optional<JobSnapshot> Scheduler::job(const JobId& id) const {
  const Job* j = find_job(id);
  if (!j) return std::nullopt;
  return snapshot(*j);
}

const JobHeader* Scheduler::header(const JobId& id) const {
  const Job* j = find_job(id);
  return j ? &j->header() : nullptr;
}

int Scheduler::tiles_per_frame(const JobId& id) const {
  const Job* j = find_job(id);
  return j ? j->grid.count() : 0;
}

std::vector<JobSnapshot> Scheduler::jobs() const {
  std::vector<JobSnapshot> out;
  for (const JobId& id : job_order_) out.push_back(snapshot(*find_job(id)));
  return out;
}

std::vector<WorkerStats> Scheduler::workers() const {
  std::vector<WorkerStats> out;
  for (const auto& [id, w] : workers_) out.push_back(w.stats);
  return out;
}

std::optional<WorkerStats> Scheduler::worker(WorkerId id) const {
  auto it = workers_.find(id);
  if (it == workers_.end()) return std::nullopt;
  return it->second.stats;
}

std::optional<Lease> Scheduler::lease(LeaseId id) const {
  auto it = leases_.find(id);
  if (it == leases_.end()) return std::nullopt;
  return it->second;
}

const Scheduler::Frame* Scheduler::find_frame(const Job& job, int frame) {
  const int fi = frame - job.spec.first_frame;
  return fi >= 0 && fi < int(job.frames.size()) ? &job.frames[size_t(fi)] : nullptr;
}

void Scheduler::append_finished(const JobId& id, const Job& job, int frame,
                                std::vector<std::pair<TileKey, TileOutput>>& out) {
  const Frame* fr = find_frame(job, frame);
  if (!fr || fr->acknowledged) return;
  for (size_t t = 0; t < fr->tiles.size(); ++t) {
    if (deliverable(job, *fr, fr->tiles[t])) out.push_back({TileKey{id, frame, int(t)}, fr->tiles[t].output});
  }
}

std::vector<std::pair<TileKey, TileOutput>> Scheduler::finished_tiles(const JobId& id) const {
  std::vector<std::pair<TileKey, TileOutput>> out;
  const Job* job = find_job(id);
  if (!job) return out;
  for (int f = job->spec.first_frame; f <= job->spec.last_frame; ++f) append_finished(id, *job, f, out);
  return out;
}

std::vector<std::pair<TileKey, TileOutput>> Scheduler::finished_tiles(const JobId& id, int frame) const {
  std::vector<std::pair<TileKey, TileOutput>> out;
  if (const Job* job = find_job(id)) append_finished(id, *job, frame, out);
  return out;
}

bool Scheduler::frame_final(const JobId& id, int frame) const {
  const Job* job = find_job(id);
  const Frame* fr = job ? find_frame(*job, frame) : nullptr;
  return fr && fr->final;
}

std::optional<TileRect> Scheduler::tile_rect(const JobId& id, int frame, int tile) const {
  const Job* job = find_job(id);
  if (!job) return std::nullopt;
  const int fi = frame - job->spec.first_frame;
  if (fi < 0 || fi >= int(job->frames.size()) || !job->grid.contains(tile)) {
    return std::nullopt;
  }
  return job->grid.rect(tile);
}

size_t Scheduler::queued_tiles() const {
  size_t n = 0;
  const auto queued = [](const Job& job) { return job.requeued.size() + size_t(job.fresh); };
  for (const auto& key : runnable_) n += queued(*find_job(std::get<2>(key)));
  for (const JobId& id : waiting_for_memory_) n += queued(*find_job(id));
  return n;
}

}  // namespace tessera::server

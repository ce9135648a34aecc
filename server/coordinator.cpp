// SPDX-License-Identifier: Apache-2.0
// The coordinator's lifetime: restoring the job store, the expiry thread that expires leases and
// evicts ended jobs, and the observers (metrics, web monitor) with their snapshots.
#include "coordinator.h"

#include <spdlog/spdlog.h>

namespace tessera::server {

namespace v1 = tessera::v1;

Coordinator::Coordinator(CoordinatorOptions options, BundleStore& store, JobStore* jobs)
    : options_(options),
      store_(store),
      jobs_store_(jobs),
      scheduler_(options.scheduler),
      deliveries_(options.delivery_lease) {
  scheduler_.set_listener(this);
  scheduler_.set_pass_planner([this](const JobId& job, int frame, int passes,
                                     const std::vector<const TileOutput*>& outputs) {
    return passes_.plan(scheduler_.header(job)->spec, job, frame, passes, outputs);
  });
  if (jobs_store_) restore_locked();  // no stream or thread exists yet
  expiry_ = std::thread([this] { expiry_loop(); });
}

Coordinator::~Coordinator() { stop(); }

void Coordinator::stop() {
  {
    std::lock_guard lock(stop_mu_);
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (expiry_.joinable()) expiry_.join();
}

void Coordinator::restore_locked() {
  // Every stored tile names itself (TileData job_id, frame, tile_index, set by the coordinator
  // when it accepted the result, and covered by the record's CRC): a record that is intact but
  // belongs elsewhere is refused like a damaged one.
  JobStore::Loaded l = jobs_store_->load([](const TileKey& row, const std::string& payload) -> std::string {
    v1::TileData t;
    if (!t.ParseFromString(payload)) return "it does not parse as a tile";
    if (t.job_id() == row.job && t.frame() == row.frame && t.tile_index() == row.tile) return {};
    return fmt::format("it is job {} frame {} tile {}", t.job_id(), t.frame(), t.tile_index());
  });
  scheduler_.set_next_lease(l.next_lease);
  int live = 0;
  int64_t tiles = 0;
  for (JobRecord& r : l.jobs) {
    const JobId id = r.id;
    if (refuse_restore_locked(r)) continue;
    r.spec.passes = FramePasses::settings_of(r.spec).has_value();  // not stored: from its overrides
    scheduler_.restore(std::move(r));
    auto s = scheduler_.job(id);
    tiles += s->tiles_done;
    if (job_ended(s->state)) {
      ended_[id] = s->ended.value_or(Clock::now());
    } else {
      ++live;
    }
    // restore() settles a job whose last tile was committed but not its state change.
    jobs_store_->job_updated(*s);
    // Its undelivered frames; when they finished is not stored: from the job's end, else now.
    const std::set<int> acknowledged(s->frames_acknowledged.begin(), s->frames_acknowledged.end());
    for (int f : s->frames_done) {
      if (!acknowledged.count(f)) frame_undelivered_locked(id, f, s->ended.value_or(Clock::now()));
    }
  }
  spdlog::info("restored {} jobs from {} ({} still to render, {} finished tiles); {} leases in flight at the last "
               "stop requeued; {} orphan tile files removed{}",
               l.jobs.size(), jobs_store_->db_path().string(), live, tiles, l.leases_requeued, l.orphans_removed,
               l.tiles_missing ? fmt::format("; {} stored tiles were missing, damaged or not what their row says "
                                             "(errors above): they will be rendered again",
                                             l.tiles_missing)
                               : std::string());
}

bool Coordinator::refuse_restore_locked(const JobRecord& r) {
  // A frame's tile table, which the job builds when the frame starts, must fit under the limits
  // a submission is held to now: a job accepted by an earlier release or under higher limits must
  // not take the coordinator's memory at every start. It is not built; the job ends, saying why.
  const int64_t tiles = r.spec.tiles_per_frame();
  const char* flag = nullptr;
  int64_t limit = 0;
  if (options_.max_job_tiles > 0 && tiles > options_.max_job_tiles) {
    flag = "--max-job-tiles";
    limit = options_.max_job_tiles;
  } else if (options_.max_resident_tiles > 0 && tiles > options_.max_resident_tiles) {
    flag = "--max-resident-tiles";
    limit = options_.max_resident_tiles;
  }
  if (!flag) return false;
  JobSnapshot s;
  s.header() = r.header();
  for (const RestoredTile& d : r.done) s.rays += d.output.rays;
  const std::string why = fmt::format("not restored at start: its {} tiles a frame are over this coordinator's limit {} "
                                      "(tessera-server {}); submit it again with larger tiles, or raise the limit",
                                      tiles, limit, flag);
  if (!job_ended(s.state)) {
    s.state = JobState::kFailed;
    s.ended = Clock::now();
    s.error = why;
  }
  jobs_store_->job_updated(s);
  jobs_store_->job_evicted(r.id);  // not loaded again at the next start; `tessera status` answers
  spdlog::error("job {} {}", r.id, why);
  return true;
}

void Coordinator::expiry_loop() {
  std::unique_lock lock(stop_mu_);
  while (!stop_cv_.wait_for(lock, options_.expiry_check, [this] { return stopping_; })) {
    locked([this] {
      scheduler_.expire();  // worker_left() finishes the dropped workers' streams
      dispatch_locked();
      expire_deliveries_locked();
      evict_expired_locked();
    });
  }
}

void Coordinator::evict_locked(const JobId& id, const char* why) {
  finish_watchers_locked(id, true);  // deliverers still attached hear the final state
  deliveries_.forget(id);
  undelivered_.forget(id);
  kept_for_delivery_.erase(id);
  if (!scheduler_.forget(id)) return;
  ended_.erase(id);
  if (jobs_store_) jobs_store_->job_evicted(id);
  spdlog::info("job {} left memory ({}); `tessera status {}` still answers from the database", id, why, id);
}

void Coordinator::evict_expired_locked() {
  const TimePoint cutoff = Clock::now() - options_.retention;
  std::vector<JobId> old;
  for (const auto& [id, t] : ended_) {
    if (t >= cutoff) continue;
    // Frames that have a place to go are not deleted because nobody took them: they stay, counted
    // against --max-undelivered-gb and reported, until a deliverer writes them.
    if (undelivered_.holds(id)) {
      if (kept_for_delivery_.insert(id).second) {
        spdlog::warn("job {} ended more than the retention time ago, but finished frames of it with a recorded output "
                     "were never delivered: they are kept until `tessera collect` or `tessera watch {}` writes them",
                     id, id);
      }
      continue;
    }
    old.push_back(id);
  }
  for (const JobId& id : old) evict_locked(id, "retention time passed");
}

void Coordinator::add_observer(SchedulerListener* observer) {
  std::lock_guard lock(mu_);  // the expiry thread already runs
  observers_.push_back(observer);
}

void Coordinator::remove_observer(SchedulerListener* observer) {
  std::lock_guard lock(mu_);  // events are delivered under it: none is in progress once we hold it
  std::erase(observers_, observer);
}

FarmSnapshot Coordinator::snapshot() {
  FarmSnapshot f = locked([&] {
    FarmSnapshot f;
    f.jobs = scheduler_.jobs();
    f.workers = scheduler_.workers();
    f.tiles_queued = scheduler_.queued_tiles();
    f.delivery = delivery_backlog_locked();
    for (const auto& [job, sink] : watchers_) f.watch_backlog += sink->queued();
    return f;
  });
  if (jobs_store_) f.store = jobs_store_->stats();  // its own lock
  return f;
}

std::vector<std::pair<TileKey, TileOutput>> Coordinator::finished_tiles(const std::string& id) {
  return locked([&] { return scheduler_.finished_tiles(id); });
}

}  // namespace tessera::server

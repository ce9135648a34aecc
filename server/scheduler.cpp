// SPDX-License-Identifier: Apache-2.0
#include "scheduler.h"

#include <algorithm>
#include <climits>
#include <cstdio>
#include <random>

namespace tessera::server {

const char* job_state_name(JobState s) {
  switch (s) {
    case JobState::kQueued: return "queued";
    case JobState::kRunning: return "running";
    case JobState::kDone: return "done";
    case JobState::kCancelled: return "cancelled";
    case JobState::kFailed: return "failed";
  }
  return "?";
}

const char* lease_end_name(LeaseEnd e) {
  switch (e) {
    case LeaseEnd::kCompleted: return "completed";
    case LeaseEnd::kLostRace: return "lost the race to another copy";
    case LeaseEnd::kCancelled: return "job cancelled";
    case LeaseEnd::kExpired: return "expired";
    case LeaseEnd::kReturned: return "returned";
    case LeaseEnd::kWorkerLeft: return "worker left";
    case LeaseEnd::kFaulted: return "faulty result";
    case LeaseEnd::kBlocklisted: return "worker blocklisted for the job";
    case LeaseEnd::kStalled: return "its worker returned nothing for too long";
  }
  return "?";
}

namespace {
JobId random_job_id() {
  // 48 random bits: short enough to type, long enough that ids of a restarted coordinator do
  // not collide with ones a stale client still holds.
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  char buf[16];
  std::snprintf(buf, sizeof buf, "%012llx", static_cast<unsigned long long>(rng() & 0xffffffffffffULL));
  return buf;
}
}  // namespace

Scheduler::Scheduler(SchedulerOptions options, NowFn now, IdFn make_id)
    : options_(options), now_(std::move(now)), make_id_(make_id ? std::move(make_id) : IdFn(random_job_id)) {}

Scheduler::Job* Scheduler::find_job(const JobId& id) {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second;
}
const Scheduler::Job* Scheduler::find_job(const JobId& id) const {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second;
}

int64_t JobSpec::tiles() const {
  return std::max<int64_t>(0, int64_t(last_frame) - first_frame + 1) * tiles_per_frame();
}

int64_t JobSpec::tiles_per_frame() const { return TileGrid(width, height, std::max(1, tile_size)).count(); }

JobId Scheduler::submit(const JobSpec& spec) {
  // The job is built aside and added only once whole: when its tiles do not fit in memory
  // (std::bad_alloc), the scheduler is left as it was, with no half-built job.
  Job built;
  built.spec = spec;
  lay_out_tiles(built);
  built.fresh = built.spec.tiles();
  job_order_.reserve(job_order_.size() + 1);
  JobId id = make_id_();
  while (jobs_.count(id)) id = make_id_();
  built.id = id;
  built.seq = next_seq_;
  built.submitted = now_();
  Job& job = jobs_.emplace(id, std::move(built)).first->second;
  ++next_seq_;
  job_order_.push_back(id);  // reserved above: does not throw
  update_runnable(job);
  events().job_submitted(snapshot(job));
  if (!has_queued(job)) set_state(job, JobState::kDone);  // degenerate: nothing to render
  return id;
}

void Scheduler::set_state(Job& job, JobState s) {
  if (job.state == s) return;
  job.state = s;
  if (job_ended(s)) job.ended = now_();
  if (s == JobState::kCancelled || s == JobState::kFailed) release_unfinished(job);
  events().job_state_changed(job.id, s);
}

Scheduler::CancelResult Scheduler::cancel(const JobId& id) {
  Job* job = find_job(id);
  if (!job) return CancelResult::kUnknownJob;
  if (job_ended(job->state)) return CancelResult::kAlreadyEnded;
  clear_queue(*job);
  // Revoke every active lease of the job: results that still arrive are stale and ignored.
  std::vector<LeaseId> active;
  for (const auto& [lid, lease] : leases_) {
    if (lease.tile.job == id) active.push_back(lid);
  }
  for (LeaseId lid : active) end_lease(lid, LeaseEnd::kCancelled, false);
  set_state(*job, JobState::kCancelled);
  return CancelResult::kCancelled;
}

Scheduler::PriorityResult Scheduler::set_priority(const JobId& id, int priority) {
  Job* job = find_job(id);
  if (!job) return PriorityResult::kUnknownJob;
  if (job_ended(job->state)) return PriorityResult::kAlreadyEnded;
  if (job->spec.priority == priority) return PriorityResult::kChanged;
  runnable_.erase(queue_key(*job));  // the key holds the priority: re-filed under the new one
  job->spec.priority = priority;
  update_runnable(*job);
  events().job_priority_changed(id, priority);
  return PriorityResult::kChanged;
}

Scheduler::AckResult Scheduler::acknowledge_frame(const JobId& id, int frame) {
  Job* job = find_job(id);
  if (!job) return AckResult::kUnknownJob;
  const int fi = frame - job->spec.first_frame;
  if (fi < 0 || fi >= int(job->frames.size())) return AckResult::kUnknownFrame;
  Frame& fr = job->frames[size_t(fi)];
  if (!fr.final) return AckResult::kNotFinished;
  if (!fr.acknowledged) {
    fr.acknowledged = true;
    drop_frame_tiles(*job, fr);  // the client has them: free the pixels and the frame's table
    memory_freed();
    events().frame_acknowledged(id, frame);
  }
  return AckResult::kAcknowledged;
}

WorkerId Scheduler::add_worker(const WorkerInfo& info) {
  const WorkerId id = next_worker_++;
  Worker& w = workers_[id];
  w.stats.id = id;
  w.stats.info = info;
  w.stats.connected = w.stats.last_seen = now_();
  threads_total_ += credit_threads(w);
  events().worker_joined(w.stats);
  return id;
}

void Scheduler::remove_worker(WorkerId id, std::string_view reason, LeaseEnd why) {
  auto it = workers_.find(id);
  if (it == workers_.end()) return;
  const std::vector<LeaseId> leases(it->second.leases.begin(), it->second.leases.end());
  WorkerStats stats = it->second.stats;  // in_flight: the tiles it held when it left
  it->second.stats.wanted = 0;  // ending its leases below must not make it wanting again
  wanting_.erase(id);
  for (LeaseId lid : leases) end_lease(lid, why, true);
  threads_total_ -= credit_threads(it->second);
  workers_.erase(it);
  events().worker_left(stats, reason);
}

void Scheduler::heartbeat(WorkerId id) {
  auto it = workers_.find(id);
  if (it == workers_.end()) return;
  // O(1): a lease lives as long as its worker is heard from (expire() drops a silent worker with
  // its leases), so no lease is touched here. Before, each message renewed every lease of its
  // worker: a map lookup per lease held, on every message.
  it->second.stats.last_seen = now_();
}

void Scheduler::request_tiles(WorkerId id, int count) {
  auto it = workers_.find(id);
  if (it == workers_.end() || count <= 0) return;
  int& wanted = it->second.stats.wanted;
  wanted = std::min(options_.max_wanted_per_worker, wanted + count);
  update_wanting(it->second);
}

void Scheduler::update_wanting(Worker& w) {
  if (w.stats.wanted > 0 && w.tiles_held < credit(w)) {
    wanting_.insert(w.stats.id);
  } else {
    wanting_.erase(w.stats.id);
  }
}

int Scheduler::credit(const Worker& w) const {
  if (options_.initial_leases_per_thread <= 0) return INT_MAX;
  const int threads = credit_threads(w);
  const int64_t earned = int64_t(options_.initial_leases_per_thread) * threads + 2 * (w.results - w.credit_base);
  return int(std::min<int64_t>(earned, std::max(options_.max_wanted_per_worker, 1)));
}

int Scheduler::lease_credit(WorkerId id) const {
  auto it = workers_.find(id);
  if (it == workers_.end()) return 0;
  const int c = credit(it->second);
  return c == INT_MAX ? c : int(std::max<int64_t>(0, c - it->second.tiles_held));
}

bool Scheduler::dispatchable() const {
  for (const QueueKey& key : runnable_) {
    if (!find_job(std::get<2>(key))->held) return true;
  }
  if (options_.speculate) {
    for (const JobId& id : speculable_) {
      const Job& job = *find_job(id);
      if (!job.held && job.state == JobState::kRunning) return true;
    }
  }
  return false;
}

bool Scheduler::hold(const JobId& id, bool held) {
  Job* job = find_job(id);
  if (!job) return false;
  job->held = held;
  return true;
}

bool Scheduler::held(const JobId& id) const {
  const Job* job = find_job(id);
  return job && job->held;
}

std::vector<Assignment> Scheduler::dispatch() {
  std::vector<Assignment> out;
  // Every worker message ends in a dispatch: with nothing to hand out, looking at each waiting
  // worker would cost workers x jobs per message for nothing.
  if (wanting_.empty() || !dispatchable()) return out;
  // Factoring's share, tiles a thread, from the queue as this dispatch finds it.
  int64_t share = int64_t(1) << 40;  // no cap (and no overflow when multiplied by threads)
  const int64_t queued = int64_t(queued_tiles());
  if (options_.factoring > 0 && threads_total_ > 0) {
    const int64_t per = int64_t(options_.factoring) * threads_total_;
    share = std::max<int64_t>(2, (queued + per - 1) / per);
  }
  // Round robin, a lease (of one tile or a span) a worker a round. A worker that got nothing in a
  // round gets nothing in the next either (within one dispatch its share is fixed, what it holds only grows and the
  // queue only shrinks), so each round looks only at the workers served in the one before: with
  // a thousand workers waiting over their share, a dispatch costs one pass over them, not one a
  // round.
  std::vector<WorkerId> ids(wanting_.begin(), wanting_.end());
  std::vector<WorkerId> served;
  while (!ids.empty()) {
    served.clear();
    for (WorkerId id : ids) {
      auto it = workers_.find(id);
      if (it == workers_.end() || !wanting_.count(id)) continue;  // satisfied in an earlier round
      Worker& w = it->second;
      // Over its share: it stays wanting and is served by a later dispatch, when what it holds
      // has gone down (its results) or the queue has grown (a new job).
      if (w.tiles_held >= share * credit_threads(w)) continue;
      std::optional<Assignment> a = next_for(w, span_for(w, share, queued));
      if (!a && options_.speculate) a = speculate_for(w);
      if (!a) continue;
      w.stats.wanted = std::max(0, w.stats.wanted - a->lease.count);
      update_wanting(w);
      out.push_back(std::move(*a));
      served.push_back(id);
    }
    ids.swap(served);
  }
  return out;
}

int Scheduler::span_for(const Worker& w, int64_t share, int64_t queued) const {
  if (!w.stats.info.reads_spans || options_.max_span_tiles <= 1) return 1;
  // The worker's rate: one tile until it has returned one (its first tiles come as soon as a
  // single tile's would), then about span_seconds of its render time over its threads.
  if (w.stats.tiles_done <= 0) return 1;
  int64_t n = std::min(options_.max_span_tiles, Lease::kMaxTiles);
  const double per_tile = w.stats.seconds / double(w.stats.tiles_done);  // one thread's
  if (per_tile > 0) {
    n = std::min<int64_t>(n, int64_t(options_.span_seconds * credit_threads(w) / per_tile));
  }
  // Factoring: a span is at most one thread's share of the queue, so spans shrink toward one
  // tile as the queue runs out and the last tiles spread over the farm.
  if (options_.factoring > 0 && threads_total_ > 0) {
    n = std::min(n, queued / (int64_t(options_.factoring) * threads_total_));
  }
  // What the worker asked for and may hold.
  n = std::min<int64_t>(n, w.stats.wanted);
  n = std::min<int64_t>(n, int64_t(credit(w)) - w.tiles_held);
  n = std::min<int64_t>(n, share * credit_threads(w) - w.tiles_held);
  return int(std::max<int64_t>(1, n));
}

std::optional<Assignment> Scheduler::next_for(Worker& w, int span) {
  // The first runnable job this worker is not blocklisted for (blocklists are short: almost
  // always the first job).
  for (auto it = runnable_.begin(); it != runnable_.end();) {
    Job& job = *find_job(std::get<2>(*it++));  // update_runnable below may erase this job's key
    if (job.held || blocked(job, w)) continue;
    // A passes job's tiles carry a plan each: one a lease.
    const auto next = take_span(job, job.spec.passes ? 1 : span);
    update_runnable(job);
    if (next) return issue(w, job, *next, false);
  }
  return std::nullopt;
}

void Scheduler::end_pass(Job& job, int fi) {
  Frame& frame = job.frames[size_t(fi)];
  const int frame_number = job.spec.first_frame + fi;
  ++frame.passes;
  PassDecision next;
  if (planner_) {
    std::vector<const TileOutput*> outputs;
    outputs.reserve(frame.tiles.size());
    for (const Tile& t : frame.tiles) outputs.push_back(&t.output);
    next = planner_(job.id, frame_number, frame.passes, outputs);
  }
  if (!next.error.empty()) {
    fail_job(job, "frame " + std::to_string(frame_number) + ": " + next.error);
    return;
  }
  int requeued = 0;
  if (!next.final) {
    // At the front of the job's queue, in tile order: a frame in its passes is older work than
    // the pilots of the frames after it, and finishing it first keeps few frames between passes
    // (the planner holds each one's statistics) and frames reaching the client in order.
    for (size_t t = std::min(frame.tiles.size(), next.plans.size()); t-- > 0;) {
      if (!next.plans[t]) continue;
      Tile& tile = frame.tiles[t];
      tile.state = TileState::kQueued;
      tile.plan = std::move(*next.plans[t]);
      --frame.done;
      --job.tiles_done;
      job.requeued.emplace_front(fi, int(t));
      ++requeued;
    }
  }
  if (requeued > 0) {
    update_runnable(job);
    return;
  }
  // The frame's last pass: its tiles are final, reported in tile order, then the frame.
  frame.final = true;
  for (size_t t = 0; t < frame.tiles.size(); ++t) {
    events().tile_finished({job.id, frame_number, int(t)}, frame.tiles[t].output, frame.tiles[t].finished_by);
  }
  events().frame_finished(job.id, frame_number);
}

int Scheduler::fault(WorkerId worker, const JobId& job_id, std::optional<LeaseId> lease, const std::string& reason) {
  Job* job = find_job(job_id);
  auto wit = workers_.find(worker);
  if (!job || wit == workers_.end()) return 0;
  if (lease) {
    auto lit = leases_.find(*lease);
    if (lit != leases_.end() && lit->second.worker == worker) end_lease(*lease, LeaseEnd::kFaulted, true);
  }
  ++wit->second.stats.refused;
  const std::string& name = wit->second.stats.info.name;
  const int faults = ++job->faults[name];
  if (faults <= options_.max_faults) {
    // A wrong result is still a result: the worker keeps the credit to get the tiles that
    // blocklist it (a session that returns nothing earns none). Past the blocklist it earns no more.
    ++wit->second.results;
    wit->second.last_progress = now_();
    update_wanting(wit->second);
  }
  const bool now_blocked = faults >= options_.max_faults && job->blocklisted.insert(name).second;
  events().worker_faulted(job_id, wit->second.stats, reason, faults, now_blocked);
  if (!now_blocked) return faults;
  // Its other tiles of this job are probably bad too: give them to someone else.
  std::vector<LeaseId> mine;
  for (LeaseId lid : wit->second.leases) {
    if (leases_.at(lid).tile.job == job_id) mine.push_back(lid);
  }
  for (LeaseId lid : mine) end_lease(lid, LeaseEnd::kBlocklisted, true);
  if (job_ended(job->state)) return faults;
  // Nobody left who may render it: fail loudly rather than wait forever. A worker that joins
  // later under a new name could have rendered it, but a job that broke every worker we have
  // is far more likely broken itself.
  bool anyone = false;
  for (const auto& [id, w] : workers_) anyone |= !blocked(*job, w);
  if (!anyone) {
    fail_job(*job, "every connected worker (" + std::to_string(workers_.size()) + ") is blocklisted for this job after " +
                       std::to_string(options_.max_faults) + " faults each; last fault: " + reason);
  }
  return faults;
}

void Scheduler::count_refused(WorkerId worker) {
  if (auto it = workers_.find(worker); it != workers_.end()) ++it->second.stats.refused;
}

void Scheduler::fail_job(Job& job, const std::string& error) {
  clear_queue(job);
  std::vector<LeaseId> active;
  for (const auto& [lid, lease] : leases_) {
    if (lease.tile.job == job.id) active.push_back(lid);
  }
  for (LeaseId lid : active) end_lease(lid, LeaseEnd::kCancelled, false);
  job.error = error;
  set_state(job, JobState::kFailed);
}

void Scheduler::restore(JobRecord rec) {
  if (jobs_.count(rec.id)) return;
  Job& job = jobs_[rec.id];
  job.header() = rec.header();
  next_seq_ = std::max(next_seq_, rec.seq + 1);
  job.blocklisted.insert(rec.blocklisted.begin(), rec.blocklisted.end());
  lay_out_tiles(job);
  const int frames = int(job.frames.size());
  const int per_frame = job.grid.count();
  // Only frames with stored tiles are laid out; the others stay a range of fresh tiles.
  for (RestoredTile& d : rec.done) {
    const int fi = d.frame - job.spec.first_frame;
    if (fi < 0 || fi >= frames || d.tile < 0 || d.tile >= per_frame) continue;
    Frame& fr = job.frames[size_t(fi)];
    lay_out_frame(job, fr);
    Tile& t = fr.tiles[size_t(d.tile)];
    if (t.state == TileState::kDone) continue;
    t.state = TileState::kDone;
    t.output = std::move(d.output);
    ++fr.done;
    ++job.tiles_done;
    job.rays += t.output.rays;
    job.tile_seconds += t.output.seconds;
  }
  if (job.spec.passes) {
    // A frame's tiles are stored only when its last pass ends, all of them at once; a crash in the
    // middle of storing them leaves a frame with some. Its other tiles are not at their last
    // pass's counts, and the passes before are not stored: the frame starts again from its pilot.
    // (The tiles stored are what the frame's last pass will make again, bit for bit.)
    for (Frame& fr : job.frames) {
      if (fr.done == 0 || fr.done == per_frame) continue;
      for (Tile& t : fr.tiles) {
        if (t.state != TileState::kDone) continue;
        t.state = TileState::kQueued;
        job.rays -= t.output.rays;
        job.tile_seconds -= t.output.seconds;
        t.output = {};
        --job.tiles_done;
      }
      fr.done = 0;
      drop_frame_tiles(job, fr);
    }
  }
  for (Frame& fr : job.frames) fr.final = fr.done == per_frame;
  for (int f : rec.acknowledged) {
    const int fi = f - job.spec.first_frame;
    if (fi < 0 || fi >= frames || !job.frames[size_t(fi)].final) continue;
    job.frames[size_t(fi)].acknowledged = true;
    drop_frame_tiles(job, job.frames[size_t(fi)]);
  }
  if (job.state == JobState::kCancelled || job.state == JobState::kFailed) release_unfinished(job);
  // A job stored as done whose tiles are not all there any more (a damaged or lost segment
  // record, dropped by the store) runs again: "done" would be a lie, and the client would be
  // told every frame is ready while one is short. Cancelled and failed jobs stay as they are.
  if (job.state == JobState::kDone && job.tiles_done < int64_t(frames) * per_frame) {
    job.state = JobState::kRunning;
    job.ended.reset();
  }
  if (!job_ended(job.state)) {
    // Leases in flight at the crash come back as queued tiles, oldest work first: the cursor
    // starts again at the first frame and passes over the tiles that are done.
    job.fresh = int64_t(frames) * per_frame - job.tiles_done;
    if (job.fresh <= 0) {
      job.state = JobState::kDone;  // the crash came between the last tile and the state change
      job.ended = now_();
    } else if (job.tiles_done == 0) {
      job.state = JobState::kQueued;
    }
  }
  // Job order is submit order, whatever order storage returned them in.
  auto pos = std::find_if(job_order_.begin(), job_order_.end(), [&](const JobId& o) { return jobs_.at(o).seq > job.seq; });
  job_order_.insert(pos, job.id);
  update_runnable(job);
}

bool Scheduler::forget(const JobId& id) {
  Job* job = find_job(id);
  if (!job || !job_ended(job->state)) return false;
  for (const auto& [lid, lease] : leases_) {
    if (lease.tile.job == id) return false;
  }
  runnable_.erase(queue_key(*job));
  speculable_.erase(id);
  waiting_for_memory_.erase(id);
  std::erase(job_order_, id);
  const bool freed = job->tiles_resident > 0;
  tiles_held_ -= job->tiles_resident;
  jobs_.erase(id);
  if (freed) memory_freed();
  return true;
}

bool Scheduler::all_acknowledged(const JobId& id) const {
  const Job* job = find_job(id);
  if (!job) return false;
  for (const Frame& fr : job->frames) {
    if (!fr.acknowledged && !fr.released) return false;  // a released frame has nothing to deliver
  }
  return true;
}

std::vector<WorkerId> Scheduler::expire() {
  const TimePoint now = now_();
  std::vector<WorkerId> silent;
  for (const auto& [id, w] : workers_) {
    if (now - w.stats.last_seen > options_.lease_timeout) silent.push_back(id);
  }
  for (WorkerId id : silent) remove_worker(id, "missed heartbeats", LeaseEnd::kExpired);
  revoke_stalled(now);
  return silent;
}

void Scheduler::revoke_stalled(TimePoint now) {
  const auto limit = std::max<Clock::duration>(
      options_.stall_timeout, std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(8 * slowest_tile_)));
  for (auto& [id, w] : workers_) {
    if (w.leases.empty() || now - w.last_progress <= limit) continue;
    const std::vector<LeaseId> held(w.leases.begin(), w.leases.end());
    for (LeaseId lid : held) end_lease(lid, LeaseEnd::kStalled, true);
    w.credit_base = w.results;  // earned again from the start, like a new session
    update_wanting(w);
  }
}

}  // namespace tessera::server

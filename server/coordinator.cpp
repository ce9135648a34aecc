#include "coordinator.h"

#include <spdlog/spdlog.h>

#include <cstring>

#include "farm/bundle.h"
#include "farm/overrides_codec.h"
#include "farm/tile_codec.h"
#include "scene/scene_parser.h"

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

namespace {
double to_unix(TimePoint t) {
  const auto sys = std::chrono::system_clock::now() - (Clock::now() - t);
  return std::chrono::duration<double>(sys.time_since_epoch()).count();
}
double seconds_since(TimePoint t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

v1::JobState to_proto(JobState s) {
  switch (s) {
    case JobState::kQueued: return v1::JOB_STATE_QUEUED;
    case JobState::kRunning: return v1::JOB_STATE_RUNNING;
    case JobState::kDone: return v1::JOB_STATE_DONE;
    case JobState::kCancelled: return v1::JOB_STATE_CANCELLED;
    case JobState::kFailed: return v1::JOB_STATE_FAILED;
  }
  return v1::JOB_STATE_UNSPECIFIED;
}
}  // namespace

Coordinator::Coordinator(CoordinatorOptions options, BundleStore& store, JobStore* jobs)
    : options_(options), store_(store), jobs_store_(jobs), scheduler_(options.scheduler) {
  scheduler_.set_listener(this);
  if (jobs_store_) restore_locked();  // no stream or thread exists yet
  expiry_ = std::thread([this] { expiry_loop(); });
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
  }
  spdlog::info("restored {} jobs from {} ({} still to render, {} finished tiles); {} leases in flight at the last "
               "stop requeued; {} orphan tile files removed{}",
               l.jobs.size(), jobs_store_->db_path().string(), live, tiles, l.leases_requeued, l.orphans_removed,
               l.tiles_missing ? fmt::format("; {} stored tiles were missing, damaged or not what their row says "
                                             "(errors above): they will be rendered again",
                                             l.tiles_missing)
                               : std::string());
}

void Coordinator::evict_locked(const JobId& id, const char* why) {
  if (!scheduler_.forget(id)) return;
  ended_.erase(id);
  if (jobs_store_) jobs_store_->job_evicted(id);
  spdlog::info("job {} left memory ({}); `tessera status {}` still answers from the database", id, why, id);
}

void Coordinator::evict_expired_locked() {
  const TimePoint cutoff = Clock::now() - options_.retention;
  std::vector<JobId> old;
  for (const auto& [id, t] : ended_) {
    if (t < cutoff) old.push_back(id);
  }
  for (const JobId& id : old) evict_locked(id, "retention time passed");
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

template <class F>
auto Coordinator::locked(F&& f) {
  std::vector<std::shared_ptr<WorkerSink>> workers;
  std::vector<std::shared_ptr<WatchSink>> watchers;
  auto pump = [&] {
    for (auto& w : workers) w->pump();
    for (auto& w : watchers) w->pump();
  };
  std::unique_lock lock(mu_);
  if constexpr (std::is_void_v<decltype(f())>) {
    f();
    workers.swap(touched_workers_);
    watchers.swap(touched_watchers_);
    lock.unlock();
    pump();
  } else {
    auto result = f();
    workers.swap(touched_workers_);
    watchers.swap(touched_watchers_);
    lock.unlock();
    pump();
    return result;
  }
}

void Coordinator::expiry_loop() {
  std::unique_lock lock(stop_mu_);
  while (!stop_cv_.wait_for(lock, options_.expiry_check, [this] { return stopping_; })) {
    locked([this] {
      scheduler_.expire();  // worker_left() finishes the dropped workers' streams
      dispatch_locked();
      evict_expired_locked();
    });
  }
}

// ------------------------------------------------------------------------------------------
// Client side

void Coordinator::status_proto(const JobSnapshot& s, v1::JobStatus* out) const {
  out->set_job_id(s.id);
  out->set_name(s.spec.name);
  out->set_state(to_proto(s.state));
  out->set_priority(s.spec.priority);
  out->set_bundle_sha256(s.spec.bundle_sha256);
  out->mutable_overrides()->ParseFromString(s.spec.overrides);
  out->set_first_frame(s.spec.first_frame);
  out->set_last_frame(s.spec.last_frame);
  out->set_width(s.spec.width);
  out->set_height(s.spec.height);
  out->set_spp(s.spec.spp);
  out->set_tile_size(s.spec.tile_size);
  out->set_tiles_per_frame(s.tiles_per_frame);
  out->set_tiles_total(s.tiles_total);
  out->set_tiles_done(s.tiles_done);
  out->set_tiles_leased(s.tiles_leased);
  out->set_tiles_rendered_twice(s.duplicates_discarded);
  out->set_rays(s.rays);
  out->set_submitted_unix(to_unix(s.submitted));
  out->set_elapsed_seconds(std::chrono::duration<double>((s.ended ? *s.ended : Clock::now()) - s.submitted).count());
  for (int f : s.frames_done) out->add_frames_done(f);
  for (int f : s.frames_acknowledged) out->add_frames_acknowledged(f);
  out->set_error(s.error);
  for (const auto& w : s.blocklisted) out->add_blocklisted_workers(w);
}

Status Coordinator::submit(const v1::SubmitJobRequest& req, v1::JobStatus* out, const Admission& admission) {
  if (jobs_store_ && !jobs_store_->healthy()) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  "the coordinator cannot write its data directory, so it takes no new jobs: " +
                      jobs_store_->last_error());
  }
  if (!farm::is_sha256_hex(req.bundle_sha256())) {
    return Status(StatusCode::INVALID_ARGUMENT,
                  "bundle_sha256 '" + req.bundle_sha256() + "' is not a lower-case hex SHA-256");
  }
  if (!store_.has(req.bundle_sha256())) {
    return Status(StatusCode::NOT_FOUND,
                  "bundle " + req.bundle_sha256() + " is not on this coordinator: upload it first (UploadBundle)");
  }
  const int tile = req.tile_size() == 0 ? 32 : req.tile_size();
  if (tile < 4 || tile > 256) {
    return Status(StatusCode::INVALID_ARGUMENT, "tile_size: must be in [4, 256], got " + std::to_string(tile));
  }
  JobSpec spec;
  Scene scene;
  try {
    // Every file the scene reads must be in its bundle: a scene cannot make the coordinator (or
    // a worker: worker/bundle_cache.cpp) read anything else.
    SceneLoadOptions options;
    options.confine_to = (store_.dir() / req.bundle_sha256()).string();
    options.max_primitives = admission.max_primitives;
    if (admission.max_texture_pixels) options.max_texture_pixels = admission.max_texture_pixels;
    options.gltf = farm::gltf_options_from_proto(req.overrides());
    scene = load_scene(store_.scene_path(req.bundle_sha256()).string(), options);
    apply_overrides(scene, farm::from_proto(req.overrides()));
  } catch (const SceneError& e) {
    // Paths in the message are relative to the bundle: the client knows its files by those
    // names, and the coordinator's --data-dir is none of its business.
    std::string what = e.what();
    const std::string prefix = (store_.dir() / req.bundle_sha256()).string() + "/";
    for (size_t at; (at = what.find(prefix)) != std::string::npos;) what.erase(at, prefix.size());
    // The primitive and texture limits are resource limits; other scene errors are the scene's fault.
    const char* flag = what.find("limit max_primitives") != std::string::npos         ? "--max-primitives"
                       : what.find("exceeds the texture limit") != std::string::npos ? "--max-texture-pixels"
                                                                                    : nullptr;
    return Status(flag ? StatusCode::RESOURCE_EXHAUSTED : StatusCode::INVALID_ARGUMENT,
                  "invalid scene: " + what + (flag ? std::string(" (tessera-server ") + flag + ")" : ""));
  } catch (const std::exception& e) {
    return Status(StatusCode::INTERNAL, std::string("cannot load the bundle's scene: ") + e.what());
  }
  spec.width = scene.image.width;
  spec.height = scene.image.height;
  // An adaptive job's spp is its most samples per pixel (what limits and estimates go by).
  spec.spp = scene.image.adaptive() ? scene.image.max_spp : scene.image.spp;
  const int frame_count = scene.frame_count();
  spec.first_frame = req.has_first_frame() ? req.first_frame() : 0;
  spec.last_frame = req.has_last_frame() ? req.last_frame() : frame_count - 1;
  if (spec.first_frame < 0 || spec.last_frame >= frame_count || spec.first_frame > spec.last_frame) {
    return Status(StatusCode::INVALID_ARGUMENT, "frames " + std::to_string(spec.first_frame) + "-" +
                                                    std::to_string(spec.last_frame) + ": the scene has frames 0-" +
                                                    std::to_string(frame_count - 1));
  }
  if (admission.check) {
    if (Status s = admission.check(scene, spec.first_frame, spec.last_frame); !s.ok()) return s;
  }
  spec.owner = admission.owner;
  spec.name = req.name();
  spec.bundle_sha256 = req.bundle_sha256();
  // The overrides as stored, sent to workers and shown to clients carry the target-error settings
  // in effect, also where they came from the scene file: `tessera watch` then knows the target
  // without the scene, and workers apply exactly the same settings.
  v1::ImageOverrides resolved = req.overrides();
  if (scene.image.adaptive()) {
    resolved.set_target_rmse(scene.image.target_rmse);
    resolved.set_min_spp(scene.image.min_spp);
    resolved.set_max_spp(scene.image.max_spp);
  }
  spec.overrides = resolved.SerializeAsString();
  spec.tile_size = tile;
  spec.priority = req.priority();
  const JobId id = locked([&] {
    const JobId id = scheduler_.submit(spec);
    status_proto(*scheduler_.job(id), out);
    dispatch_locked();
    return id;
  });
  // SubmitJob answers OK only once the job is durable: a client never holds the id of a job a
  // coordinator crash could forget.
  if (jobs_store_) {
    const std::string err = jobs_store_->barrier().get();
    if (!err.empty()) {
      locked([&] { scheduler_.cancel(id); });
      return Status(StatusCode::RESOURCE_EXHAUSTED, "the job could not be stored, so it was not accepted: " + err);
    }
  }
  return Status::OK;
}

std::optional<JobSnapshot> Coordinator::evicted_job(const std::string& id) {
  if (!jobs_store_) return std::nullopt;
  // The job may have left memory a moment ago, its last rows still queued: read after they are
  // committed. Called without mu_ held.
  jobs_store_->barrier().get();
  return jobs_store_->read_job(id);
}

std::vector<std::pair<std::string, std::string>> Coordinator::active_jobs_by_owner() {
  return locked([&] {
    std::vector<std::pair<std::string, std::string>> out;
    for (const JobSnapshot& s : scheduler_.jobs()) {
      if (!s.spec.owner.empty() && !job_ended(s.state)) out.emplace_back(s.spec.owner, s.id);
    }
    return out;
  });
}

Status Coordinator::get_job(const std::string& id, v1::JobStatus* out) {
  const bool resident = locked([&] {
    auto s = scheduler_.job(id);
    if (s) status_proto(*s, out);
    return s.has_value();
  });
  if (resident) return Status::OK;
  if (auto s = evicted_job(id)) {
    status_proto(*s, out);
    return Status::OK;
  }
  return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
}

std::optional<std::string> Coordinator::job_owner(const std::string& id) {
  auto owner = locked([&]() -> std::optional<std::string> {
    if (auto s = scheduler_.job(id)) return s->spec.owner;
    return std::nullopt;
  });
  if (owner) return owner;
  if (auto s = evicted_job(id)) return s->spec.owner;
  return std::nullopt;
}

void Coordinator::list_jobs(v1::ListJobsResponse* out) {
  locked([&] {
    for (const auto& s : scheduler_.jobs()) status_proto(s, out->add_jobs());
  });
}

Status Coordinator::cancel(const std::string& id, v1::JobStatus* out) {
  return locked([&] {
    switch (scheduler_.cancel(id)) {
      case Scheduler::CancelResult::kUnknownJob:
        return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
      case Scheduler::CancelResult::kAlreadyEnded:
      case Scheduler::CancelResult::kCancelled:
        break;
    }
    status_proto(*scheduler_.job(id), out);
    return Status::OK;
  });
}

Status Coordinator::set_priority(const std::string& id, int priority, v1::JobStatus* out) {
  return locked([&] {
    switch (scheduler_.set_priority(id, priority)) {
      case Scheduler::PriorityResult::kUnknownJob:
        return Status(StatusCode::NOT_FOUND, "no job '" + id + "' in this coordinator's queue");
      case Scheduler::PriorityResult::kAlreadyEnded:
        return Status(StatusCode::FAILED_PRECONDITION,
                      "job " + id + " has ended (" + job_state_name(scheduler_.job(id)->state) +
                          "): its priority no longer matters");
      case Scheduler::PriorityResult::kChanged:
        break;
    }
    status_proto(*scheduler_.job(id), out);
    dispatch_locked();
    return Status::OK;
  });
}

void Coordinator::add_observer(SchedulerListener* observer) {
  std::lock_guard lock(mu_);  // the expiry thread already runs
  observers_.push_back(observer);
}

FarmSnapshot Coordinator::snapshot() {
  FarmSnapshot f = locked([&] {
    FarmSnapshot f;
    f.jobs = scheduler_.jobs();
    f.workers = scheduler_.workers();
    f.tiles_queued = scheduler_.queued_tiles();
    for (const auto& [job, sink] : watchers_) f.watch_backlog += sink->queued();
    return f;
  });
  if (jobs_store_) f.store = jobs_store_->stats();  // its own lock
  return f;
}

std::vector<std::pair<TileKey, TileOutput>> Coordinator::finished_tiles(const std::string& id) {
  return locked([&] { return scheduler_.finished_tiles(id); });
}

Status Coordinator::ack_frame(const std::string& id, int frame) {
  Status s = locked([&] {
    switch (scheduler_.acknowledge_frame(id, frame)) {
      case Scheduler::AckResult::kAcknowledged:
        if (auto s = scheduler_.job(id); s && job_ended(s->state) && scheduler_.all_acknowledged(id)) {
          evict_locked(id, "every frame delivered");
        }
        return Status::OK;
      case Scheduler::AckResult::kUnknownJob:
        // Evicted: every frame was acknowledged already (or its retention time passed). Its row
        // was committed at submit, so no barrier is needed to find it.
        if (jobs_store_ && jobs_store_->read_job(id)) return Status::OK;
        return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
      case Scheduler::AckResult::kUnknownFrame:
        return Status(StatusCode::INVALID_ARGUMENT, "job " + id + " has no frame " + std::to_string(frame));
      case Scheduler::AckResult::kNotFinished:
        return Status(StatusCode::FAILED_PRECONDITION,
                      "frame " + std::to_string(frame) + " of job " + id + " is not finished");
    }
    return Status::OK;
  });
  // AckFrame answers OK only once the acknowledgement is durable (with the frame's tile rows:
  // the same batch or an earlier one), so a frame a client was told is acknowledged is never
  // rendered again, not even after kill -9 (issue 15). Group commit: one fsync per batch.
  if (s.ok() && jobs_store_) {
    // While storage is failing (a full disk), batches are retried once a second: waiting for one
    // per frame would stall the client a second per frame. Say so at once instead; the
    // acknowledgement is kept in memory and stored with the next batch that goes through.
    if (!jobs_store_->healthy()) {
      return Status(StatusCode::UNAVAILABLE, "frame " + std::to_string(frame) + " of job " + id +
                                                 " is acknowledged but cannot be stored right now (" +
                                                 jobs_store_->last_error() + "): it will be once storage recovers");
    }
    if (const std::string err = jobs_store_->barrier().get(); !err.empty()) {
      return Status(StatusCode::UNAVAILABLE, "frame " + std::to_string(frame) + " of job " + id +
                                                 " is acknowledged but not yet stored (" + err +
                                                 "): acknowledge it again later");
    }
    spdlog::debug("job {} frame {} acknowledgement stored", id, frame);
  }
  return s;
}

void Coordinator::list_workers(v1::ListWorkersResponse* out) {
  locked([&] {
    for (const auto& w : scheduler_.workers()) {
      auto* p = out->add_workers();
      p->set_worker_id(std::to_string(w.id));
      p->set_name(w.info.name);
      p->set_peer(w.info.peer);
      p->set_threads(w.info.threads);
      p->set_embree_isa(w.info.embree_isa);
      p->set_tiles_in_flight(w.in_flight);
      p->set_tiles_done(w.tiles_done);
      p->set_rays(w.rays);
      p->set_render_seconds(w.seconds);
      p->set_connected_seconds(seconds_since(w.connected));
      p->set_since_heartbeat_seconds(seconds_since(w.last_seen));
    }
  });
}

Status Coordinator::attach_watcher(const std::string& id, std::shared_ptr<WatchSink> sink) {
  Status st = attach_resident(id, sink);
  if (st.error_code() != StatusCode::NOT_FOUND) return st;
  // Evicted: ended, and its frames delivered. The final status is all there is to send.
  if (auto old = evicted_job(id)) {
    v1::WatchJobEvent ev;
    status_proto(*old, ev.mutable_status());
    sink->push(ev);
    sink->finish(Status::OK);
    sink->pump();
    return Status::OK;
  }
  return st;
}

Status Coordinator::attach_resident(const std::string& id, const std::shared_ptr<WatchSink>& sink) {
  return locked([&] {
    auto s = scheduler_.job(id);
    if (!s) return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
    v1::WatchJobEvent ev;
    status_proto(*s, ev.mutable_status());
    sink->push(ev);
    // Every finished tile not yet acknowledged, frame by frame, each complete frame closed by
    // frame_done: a client that re-attaches gets exactly what it is missing.
    const std::set<int> done(s->frames_done.begin(), s->frames_done.end());
    int current = -1;
    auto close_frame = [&](int f) {
      if (f >= 0 && done.count(f)) {
        v1::WatchJobEvent fd;
        fd.set_frame_done(f);
        sink->push(fd);
      }
    };
    for (const auto& [key, output] : scheduler_.finished_tiles(id)) {
      if (key.frame != current) close_frame(current);
      current = key.frame;
      push_tile_locked(id, sink, output.payload);
    }
    close_frame(current);
    if (job_ended(s->state)) {
      sink->finish(Status::OK);  // the first status event already carries the final state
    } else {
      watchers_.emplace(id, sink);
    }
    touched_watchers_.push_back(sink);
    return Status::OK;
  });
}

void Coordinator::detach_watcher(const std::shared_ptr<WatchSink>& sink) {
  locked([&] {
    std::set<JobId> jobs;
    for (auto it = watchers_.begin(); it != watchers_.end();) {
      if (it->second == sink) {
        jobs.insert(it->first);
        it = watchers_.erase(it);
      } else {
        ++it;
      }
    }
    // A stream that held its job back no longer does once it is gone.
    if (sink->throttled.exchange(false)) {
      for (const JobId& job : jobs) release_if_caught_up_locked(job);
    }
  });
}

void Coordinator::watcher_drained(const std::shared_ptr<WatchSink>& sink) {
  locked([&] {
    if (!sink->throttled.exchange(false)) return;
    std::set<JobId> jobs;
    for (const auto& [job, s] : watchers_) {
      if (s == sink) jobs.insert(job);
    }
    for (const JobId& job : jobs) release_if_caught_up_locked(job);
  });
}

void Coordinator::push_tile_locked(const JobId& job, const std::shared_ptr<WatchSink>& sink,
                                   const std::shared_ptr<const std::string>& payload) {
  // The scheduler keeps the encoded tile until its frame is acknowledged; the stream only refers
  // to it and parses it when the tile's turn to be written comes.
  sink->push_deferred([payload](v1::WatchJobEvent* ev) { ev->mutable_tile()->ParseFromString(*payload); });
  touched_watchers_.push_back(sink);
  const size_t bound = options_.watch_backlog_tiles;
  if (bound == 0 || sink->throttled.load() || sink->queued() < bound) return;
  sink->throttled = true;
  if (!scheduler_.held(job) && scheduler_.hold(job, true)) {
    spdlog::debug("job {} held: a watch stream has {} tiles queued, the client reads slower than the farm renders",
                  job, sink->queued());
  }
}

void Coordinator::release_if_caught_up_locked(const JobId& job) {
  if (!scheduler_.held(job)) return;
  auto [b, e] = watchers_.equal_range(job);
  for (auto it = b; it != e; ++it) {
    if (it->second->throttled.load()) return;
  }
  scheduler_.hold(job, false);
  spdlog::debug("job {} released: its watch streams caught up", job);
  dispatch_locked();
}

// ------------------------------------------------------------------------------------------
// Worker side

WorkerId Coordinator::register_worker(const WorkerInfo& info, std::shared_ptr<WorkerSink> sink) {
  return locked([&] {
    const WorkerId id = scheduler_.add_worker(info);
    workers_[id] = sink;
    v1::CoordinatorMessage m;
    m.mutable_welcome()->set_worker_id(std::to_string(id));
    m.mutable_welcome()->set_heartbeat_interval_ms(int(options_.heartbeat_interval.count()));
    m.mutable_welcome()->set_lease_timeout_ms(int(options_.scheduler.lease_timeout.count()));
    sink->push(m);
    touched_workers_.push_back(sink);
    return id;
  });
}

void Coordinator::worker_gone(WorkerId id, std::string_view reason) {
  locked([&] {
    scheduler_.remove_worker(id, reason);
    workers_.erase(id);
    dispatch_locked();
  });
}

void Coordinator::worker_message(WorkerId id, const v1::WorkerMessage& msg) {
  locked([&] {
    scheduler_.heartbeat(id);  // any message is a sign of life
    switch (msg.msg_case()) {
      case v1::WorkerMessage::kRequest:
        scheduler_.request_tiles(id, msg.request().count());
        break;
      case v1::WorkerMessage::kResult:
        tile_result_locked(id, msg.result());
        break;
      case v1::WorkerMessage::kReturned:
        scheduler_.return_leases(id, {msg.returned().lease_ids().begin(), msg.returned().lease_ids().end()});
        break;
      case v1::WorkerMessage::kFailed: {
        auto lease = scheduler_.lease(msg.failed().lease_id());
        if (!lease || lease->worker != id) break;  // revoked meanwhile: nothing to count
        scheduler_.fault(id, lease->tile.job, lease->id,
                         fmt::format("frame {} tile {}: worker cannot render: {}", lease->tile.frame, lease->tile.tile,
                                     msg.failed().reason()));
        break;
      }
      default:
        break;
    }
    dispatch_locked();
  });
}

void Coordinator::tile_result_locked(WorkerId id, const v1::TileResult& r) {
  auto lease = scheduler_.lease(r.lease_id());
  if (!lease || lease->worker != id) {
    // A lease this worker held and lost (revoked, expired, from before a restart) is normal
    // traffic. A lease id never issued, or another worker's live lease, is a lie: a fault.
    const bool never_issued = r.lease_id() == 0 || r.lease_id() >= scheduler_.next_lease();
    if (!never_issued && !lease) {
      spdlog::debug("worker {}: result for lease {} ignored (revoked, expired or from before a restart)", id,
                    r.lease_id());
      return;
    }
    const std::string why = never_issued
                                ? fmt::format("stale lease {}: never issued by this coordinator", r.lease_id())
                                : fmt::format("lease {} belongs to worker {}", r.lease_id(), lease->worker);
    if (scheduler_.fault(id, r.tile().job_id(), std::nullopt,
                         fmt::format("frame {} tile {}: {}", r.tile().frame(), r.tile().tile_index(), why)) == 0) {
      spdlog::warn("worker {}: refused a result for unknown job '{}': {}", id, r.tile().job_id(), why);
    }
    return;
  }
  const auto rect = scheduler_.tile_rect(lease->tile.job, lease->tile.frame, lease->tile.tile);
  const std::string err = farm::validate_tile(r.tile(), *rect);
  if (!err.empty()) {
    scheduler_.fault(id, lease->tile.job, lease->id,
                     fmt::format("frame {} tile {}: {}", lease->tile.frame, lease->tile.tile, err));
    return;
  }
  // The coordinator is the authority on what the tile is: overwrite the identifying fields.
  v1::TileData tile = r.tile();
  tile.set_job_id(lease->tile.job);
  tile.set_frame(lease->tile.frame);
  tile.set_tile_index(lease->tile.tile);
  if (auto w = scheduler_.worker(id)) tile.set_worker(w->info.name);
  TileOutput out;
  out.rays = tile.rays().camera() + tile.rays().shadow() + tile.rays().secondary();
  out.seconds = tile.seconds();
  out.payload = std::make_shared<const std::string>(tile.SerializeAsString());
  const auto outcome = scheduler_.complete(id, r.lease_id(), std::move(out));
  // One line per result received: tests count re-rendered tiles from these.
  spdlog::debug("result: lease {} job {} frame {} tile {} from worker {}: {}", r.lease_id(), lease->tile.job,
                lease->tile.frame, lease->tile.tile, id,
                outcome == Scheduler::ResultOutcome::kAccepted ? "accepted" : "duplicate");
}

void Coordinator::dispatch_locked() {
  for (const Assignment& a : scheduler_.dispatch()) {
    auto it = workers_.find(a.lease.worker);
    if (it == workers_.end()) continue;
    v1::CoordinatorMessage m;
    auto* p = m.mutable_assignment();
    p->set_lease_id(a.lease.id);
    p->set_deadline_unix_ms(int64_t(to_unix(a.lease.deadline) * 1000));
    p->set_job_id(a.lease.tile.job);
    p->set_bundle_sha256(a.bundle_sha256);
    p->mutable_overrides()->ParseFromString(a.overrides);
    p->set_frame(a.lease.tile.frame);
    p->set_tile_index(a.lease.tile.tile);
    farm::to_proto(a.rect, p->mutable_rect());
    it->second->push(std::move(m));
    touched_workers_.push_back(it->second);
  }
}

// ------------------------------------------------------------------------------------------
// Scheduler events (under mu_)

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
  if (!job_ended(state)) return;
  auto [b, e] = watchers_.equal_range(id);
  for (auto it = b; it != e; ++it) {
    v1::WatchJobEvent ev;
    status_proto(*s, ev.mutable_status());
    it->second->push(ev);
    it->second->finish(Status::OK);
    touched_watchers_.push_back(it->second);
  }
  watchers_.erase(id);
}

void Coordinator::tile_leased(const Assignment& a) {
  notify([&](SchedulerListener& o) { o.tile_leased(a); });

  if (jobs_store_) jobs_store_->lease_issued(a.lease, std::to_string(a.lease.worker));
  spdlog::debug("lease {} job {} frame {} tile {} to worker {}{}", a.lease.id, a.lease.tile.job, a.lease.tile.frame,
                a.lease.tile.tile, a.lease.worker, a.lease.speculative ? " (speculative copy)" : "");
}

void Coordinator::lease_ended(const Lease& lease, LeaseEnd why) {
  notify([&](SchedulerListener& o) { o.lease_ended(lease, why); });

  if (jobs_store_) jobs_store_->lease_ended(lease.id);
  if (why == LeaseEnd::kExpired) {
    spdlog::warn("lease {} of worker {} expired: job {} frame {} tile {} requeued", lease.id, lease.worker,
                 lease.tile.job, lease.tile.frame, lease.tile.tile);
  }
  if (why != LeaseEnd::kLostRace && why != LeaseEnd::kCancelled && why != LeaseEnd::kBlocklisted) return;
  auto it = workers_.find(lease.worker);
  if (it == workers_.end()) return;
  v1::CoordinatorMessage m;
  m.mutable_revoke()->add_lease_ids(lease.id);
  it->second->push(std::move(m));
  touched_workers_.push_back(it->second);
}

void Coordinator::tile_finished(const TileKey& key, const TileOutput& out, WorkerId worker) {
  notify([&](SchedulerListener& o) { o.tile_finished(key, out, worker); });

  if (jobs_store_) jobs_store_->tile_done(key, out);
  if (auto it = awaiting_first_tile_.find(key.job); it != awaiting_first_tile_.end()) {
    spdlog::info("job {} first tile {:.3f} s after submit", key.job,
                 std::chrono::duration<double>(Clock::now() - it->second).count());
    awaiting_first_tile_.erase(it);
  }
  auto [b, e] = watchers_.equal_range(key.job);
  for (auto it = b; it != e; ++it) push_tile_locked(key.job, it->second, out.payload);
}

void Coordinator::job_priority_changed(const JobId& id, int priority) {
  notify([&](SchedulerListener& o) { o.job_priority_changed(id, priority); });
  if (jobs_store_) jobs_store_->job_updated(*scheduler_.job(id));
  spdlog::info("job {} priority set to {}", id, priority);
}

void Coordinator::frame_finished(const JobId& id, int frame) {
  notify([&](SchedulerListener& o) { o.frame_finished(id, frame); });

  spdlog::info("job {} frame {} finished", id, frame);
  auto [b, e] = watchers_.equal_range(id);
  for (auto it = b; it != e; ++it) {
    v1::WatchJobEvent ev;
    ev.set_frame_done(frame);
    it->second->push(ev);
    touched_watchers_.push_back(it->second);
  }
}

void Coordinator::frame_acknowledged(const JobId& id, int frame) {
  notify([&](SchedulerListener& o) { o.frame_acknowledged(id, frame); });

  if (jobs_store_) {
    if (const auto s = scheduler_.job(id)) jobs_store_->frame_acknowledged(id, frame, s->tiles_per_frame);
  }
  spdlog::info("job {} frame {} delivered to the client; its tiles are released", id, frame);
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

  spdlog::info("worker {} '{}' left ({}): {} tiles rendered, {} leases requeued", w.id, w.info.name, reason,
               w.tiles_done, w.in_flight);
  auto it = workers_.find(w.id);
  if (it == workers_.end()) return;
  it->second->finish(Status(StatusCode::UNAVAILABLE, "coordinator dropped this worker: " + std::string(reason)));
  touched_workers_.push_back(it->second);
  workers_.erase(it);
}

}  // namespace tessera::server

namespace tessera::server {

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

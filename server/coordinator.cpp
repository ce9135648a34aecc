#include "coordinator.h"

#include <spdlog/spdlog.h>

#include "farm/bundle.h"
#include "farm/codec.h"
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
  }
  return v1::JOB_STATE_UNSPECIFIED;
}
}  // namespace

Coordinator::Coordinator(CoordinatorOptions options, BundleStore& store)
    : options_(options), store_(store), scheduler_(options.scheduler) {
  scheduler_.set_listener(this);
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
}

Status Coordinator::submit(const v1::SubmitJobRequest& req, v1::JobStatus* out) {
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
  int frame_count = 0;
  try {
    Scene scene = load_scene(store_.scene_path(req.bundle_sha256()).string());
    apply_overrides(scene, farm::from_proto(req.overrides()));
    spec.width = scene.image.width;
    spec.height = scene.image.height;
    spec.spp = scene.image.spp;
    frame_count = scene.frame_count();
  } catch (const SceneError& e) {
    return Status(StatusCode::INVALID_ARGUMENT, std::string("invalid scene: ") + e.what());
  } catch (const std::exception& e) {
    return Status(StatusCode::INTERNAL, std::string("cannot load the bundle's scene: ") + e.what());
  }
  spec.first_frame = req.has_first_frame() ? req.first_frame() : 0;
  spec.last_frame = req.has_last_frame() ? req.last_frame() : frame_count - 1;
  if (spec.first_frame < 0 || spec.last_frame >= frame_count || spec.first_frame > spec.last_frame) {
    return Status(StatusCode::INVALID_ARGUMENT, "frames " + std::to_string(spec.first_frame) + "-" +
                                                    std::to_string(spec.last_frame) + ": the scene has frames 0-" +
                                                    std::to_string(frame_count - 1));
  }
  spec.name = req.name();
  spec.bundle_sha256 = req.bundle_sha256();
  spec.overrides = req.overrides().SerializeAsString();
  spec.tile_size = tile;
  spec.priority = req.priority();
  return locked([&] {
    const JobId id = scheduler_.submit(spec);
    status_proto(*scheduler_.job(id), out);
    dispatch_locked();
    return Status::OK;
  });
}

Status Coordinator::get_job(const std::string& id, v1::JobStatus* out) {
  return locked([&] {
    auto s = scheduler_.job(id);
    if (!s) return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
    status_proto(*s, out);
    return Status::OK;
  });
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

Status Coordinator::ack_frame(const std::string& id, int frame) {
  return locked([&] {
    switch (scheduler_.acknowledge_frame(id, frame)) {
      case Scheduler::AckResult::kAcknowledged: return Status::OK;
      case Scheduler::AckResult::kUnknownJob:
        return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
      case Scheduler::AckResult::kUnknownFrame:
        return Status(StatusCode::INVALID_ARGUMENT, "job " + id + " has no frame " + std::to_string(frame));
      case Scheduler::AckResult::kNotFinished:
        return Status(StatusCode::FAILED_PRECONDITION,
                      "frame " + std::to_string(frame) + " of job " + id + " is not finished");
    }
    return Status::OK;
  });
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
      v1::WatchJobEvent te;
      te.mutable_tile()->ParseFromString(*output.payload);
      sink->push(std::move(te));
    }
    close_frame(current);
    if (s->state == JobState::kDone || s->state == JobState::kCancelled) {
      sink->finish(Status::OK);  // the first status event already carries the final state
    } else {
      watchers_.emplace(id, sink);
    }
    touched_watchers_.push_back(sink);
    return Status::OK;
  });
}

void Coordinator::detach_watcher(const std::shared_ptr<WatchSink>& sink) {
  std::lock_guard lock(mu_);
  for (auto it = watchers_.begin(); it != watchers_.end();) {
    it = it->second == sink ? watchers_.erase(it) : std::next(it);
  }
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
      default:
        break;
    }
    dispatch_locked();
  });
}

void Coordinator::tile_result_locked(WorkerId id, const v1::TileResult& r) {
  auto lease = scheduler_.lease(r.lease_id());
  if (!lease || lease->worker != id) {
    spdlog::debug("worker {}: result for lease {} ignored (revoked, expired or not its own)", id, r.lease_id());
    return;
  }
  const auto rect = scheduler_.tile_rect(lease->tile.job, lease->tile.frame, lease->tile.tile);
  const std::string err = farm::check_tile(r.tile(), rect->width, rect->height);
  if (!err.empty() || r.tile().rect().x0() != rect->x0 || r.tile().rect().y0() != rect->y0) {
    spdlog::warn("worker {}: refused tile {} of job {} frame {}: {}; requeued", id, lease->tile.tile, lease->tile.job,
                 lease->tile.frame, err.empty() ? "wrong position" : err);
    scheduler_.return_leases(id, {r.lease_id()});
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
  scheduler_.complete(id, r.lease_id(), std::move(out));
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
    p->mutable_rect()->set_x0(a.rect.x0);
    p->mutable_rect()->set_y0(a.rect.y0);
    p->mutable_rect()->set_width(a.rect.width);
    p->mutable_rect()->set_height(a.rect.height);
    it->second->push(std::move(m));
    touched_workers_.push_back(it->second);
  }
}

// ------------------------------------------------------------------------------------------
// Scheduler events (under mu_)

void Coordinator::job_submitted(const JobSnapshot& s) {
  spdlog::info("job {} submitted: '{}', frames {}-{}, {}x{} {} spp, {} tiles of {} px, priority {}", s.id,
               s.spec.name, s.spec.first_frame, s.spec.last_frame, s.spec.width, s.spec.height, s.spec.spp,
               s.tiles_total, s.spec.tile_size, s.spec.priority);
}

void Coordinator::job_state_changed(const JobId& id, JobState state) {
  auto s = scheduler_.job(id);
  if (state == JobState::kDone) {
    spdlog::info("job {} done in {:.2f} s: {} tiles, {:.1f} Mrays, {} duplicate results discarded", id,
                 std::chrono::duration<double>(*s->ended - s->submitted).count(), s->tiles_done, s->rays / 1e6,
                 s->duplicates_discarded);
  } else {
    spdlog::info("job {} {}", id, job_state_name(state));
  }
  if (state != JobState::kDone && state != JobState::kCancelled) return;
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

void Coordinator::lease_ended(const Lease& lease, LeaseEnd why) {
  if (why == LeaseEnd::kExpired) {
    spdlog::warn("lease {} of worker {} expired: job {} frame {} tile {} requeued", lease.id, lease.worker,
                 lease.tile.job, lease.tile.frame, lease.tile.tile);
  }
  if (why != LeaseEnd::kLostRace && why != LeaseEnd::kCancelled) return;
  auto it = workers_.find(lease.worker);
  if (it == workers_.end()) return;
  v1::CoordinatorMessage m;
  m.mutable_revoke()->add_lease_ids(lease.id);
  it->second->push(std::move(m));
  touched_workers_.push_back(it->second);
}

void Coordinator::tile_finished(const TileKey& key, const TileOutput& out, WorkerId) {
  auto [b, e] = watchers_.equal_range(key.job);
  if (b == e) return;
  v1::WatchJobEvent ev;
  ev.mutable_tile()->ParseFromString(*out.payload);
  for (auto it = b; it != e; ++it) {
    it->second->push(ev);
    touched_watchers_.push_back(it->second);
  }
}

void Coordinator::frame_finished(const JobId& id, int frame) {
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
  spdlog::info("job {} frame {} delivered to the client; its tiles are released", id, frame);
}

void Coordinator::worker_joined(const WorkerStats& w) {
  spdlog::info("worker {} '{}' joined from {}: {} threads, Embree {}", w.id, w.info.name, w.info.peer,
               w.info.threads, w.info.embree_isa);
  if (!isas_.empty() && !isas_.count(w.info.embree_isa)) {
    spdlog::warn("worker {} '{}' runs Embree {} kernels, other workers ran {}: tiles may differ in the last bits",
                 w.id, w.info.name, w.info.embree_isa, *isas_.begin());
  }
  isas_.insert(w.info.embree_isa);
}

void Coordinator::worker_left(const WorkerStats& w, std::string_view reason) {
  spdlog::info("worker {} '{}' left ({}): {} tiles rendered, {} leases requeued", w.id, w.info.name, reason,
               w.tiles_done, w.in_flight);
  auto it = workers_.find(w.id);
  if (it == workers_.end()) return;
  it->second->finish(Status(StatusCode::UNAVAILABLE, "coordinator dropped this worker: " + std::string(reason)));
  touched_workers_.push_back(it->second);
  workers_.erase(it);
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// The coordinator's job API: submission (the scene parsed once, with the admission limits), status,
// cancellation, priority and frame acknowledgement. Jobs evicted from memory answer from the job store.
#include "coordinator.h"

#include <spdlog/spdlog.h>

#include "farm/bundle.h"
#include "farm/overrides_codec.h"
#include "farm/peer_text.h"
#include "farm/request_limits.h"
#include "farm/tile_codec.h"
#include "scene/scene_parser.h"

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

namespace {

// Loads the scene of a submitted job from its bundle with the admission's resource limits. The
// error says what is wrong in the client's terms: RESOURCE_EXHAUSTED for a limit (naming the
// server flag), INVALID_ARGUMENT for a faulty scene.
Status load_submitted_scene(BundleStore& store, const v1::SubmitJobRequest& req, const Admission& admission,
                            Scene* scene) {
  try {
    // Every file the scene reads must be in its bundle: a scene cannot make the coordinator (or
    // a worker: lib/farm/bundle_cache.cpp) read anything else.
    SceneLoadOptions options;
    options.confine_to = (store.dir() / req.bundle_sha256()).string();
    options.max_primitives = admission.max_primitives;
    if (admission.max_texture_pixels) options.max_texture_pixels = admission.max_texture_pixels;
    options.gltf = farm::gltf_options_from_proto(req.overrides());
    *scene = load_scene(store.scene_path(req.bundle_sha256()).string(), options);
    apply_overrides(*scene, farm::from_proto(req.overrides()));
  } catch (const SceneError& e) {
    // Paths in the message are relative to the bundle: the client knows its files by those
    // names, and the coordinator's --data-dir is none of its business.
    std::string what = e.what();
    const std::string prefix = (store.dir() / req.bundle_sha256()).string() + "/";
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
  return Status::OK;
}

// The job a submission asks for, from its request and its parsed scene: frames checked against the
// scene, then the admission's checks that need the scene.
// A recorded output is stored and shown to every client of the job: bounded, and a path a client
// elsewhere can use (absolute: a relative one would land wherever the attaching client runs).
Status check_output(const v1::JobOutput& o) {
  constexpr size_t kMaxPattern = 4096, kMaxOption = 64;
  const std::string& p = o.pattern();
  if (p.empty() || p.front() != '/' || p.size() > kMaxPattern || p.find('\0') != std::string::npos) {
    return Status(StatusCode::INVALID_ARGUMENT, "output.pattern: must be an absolute path of at most " +
                                                    std::to_string(kMaxPattern) + " bytes, got '" +
                                                    farm::peer_text(p, 200) + "'");
  }
  for (const std::string* option : {&o.tonemap(), &o.format(), &o.dither(), &o.exr_compression()}) {
    if (option->size() > kMaxOption) {
      return Status(StatusCode::INVALID_ARGUMENT, "output: an option of " + std::to_string(option->size()) +
                                                      " bytes, over " + std::to_string(kMaxOption));
    }
  }
  return Status::OK;
}

Status job_spec(const v1::SubmitJobRequest& req, const Scene& scene, const Admission& admission, int tile,
                JobSpec* out) {
  JobSpec& spec = *out;
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
    if (Status s = admission.check(scene, spec.first_frame, spec.last_frame, tile); !s.ok()) return s;
  }
  if (scene.image.sampler == SamplerKind::kLattice) {
    // Its pilot is a whole-frame lattice the farm's passes do not plan: workers would render the
    // tiles with the default sampler, a different frame from the one `tessera render` makes.
    return Status(StatusCode::INVALID_ARGUMENT,
                  "sampler lattice: renders in-process only (tessera render); the farm's passes do not plan it. "
                  "Submit with --sampler sobol (the default)");
  }
  spec.owner = admission.owner;
  spec.name = req.name();
  spec.bundle_sha256 = req.bundle_sha256();
  // The overrides as stored, sent to workers and shown to clients carry the target-error settings
  // in effect, also where they came from the scene file: `tessera watch` then knows the target
  // without the scene, and workers apply exactly the same settings.
  v1::ImageOverrides resolved = req.overrides();
  if (scene.image.adaptive()) {
    // One target, the one in effect; for a frame target the sampler too (the coordinator plans
    // its passes with the sampler's rate: sampling/pass_plan.h).
    if (scene.image.frame_target()) {
      resolved.set_target_rmse(scene.image.target_rmse);
      resolved.clear_block_rmse();
      resolved.set_sampler(sampler_name(scene.image.sampler));
    } else {
      resolved.set_block_rmse(scene.image.block_rmse);
      resolved.clear_target_rmse();
    }
    resolved.set_min_spp(scene.image.first_spp());
    resolved.set_max_spp(scene.image.max_spp);
  }
  spec.passes = scene.image.frame_target();
  spec.overrides = resolved.SerializeAsString();
  if (req.has_output()) {
    if (Status s = check_output(req.output()); !s.ok()) return s;
    spec.output = req.output().SerializeAsString();
  }
  spec.tile_size = tile;
  spec.priority = req.priority();
  return Status::OK;
}

}  // namespace

Status Coordinator::submit(const v1::SubmitJobRequest& req, v1::JobStatus* out, const Admission& admission) {
  if (jobs_store_ && !jobs_store_->healthy()) {
    return Status(StatusCode::RESOURCE_EXHAUSTED,
                  "the coordinator cannot write its data directory, so it takes no new jobs: " +
                      jobs_store_->last_error());
  }
  if (!farm::is_sha256_hex(req.bundle_sha256())) {
    return Status(StatusCode::INVALID_ARGUMENT,
                  "bundle_sha256 '" + farm::peer_text(req.bundle_sha256(), 80) + "' is not a lower-case hex SHA-256");
  }
  if (!store_.has(req.bundle_sha256())) {
    return Status(StatusCode::NOT_FOUND,
                  "bundle " + req.bundle_sha256() + " is not on this coordinator: upload it first (UploadBundle)");
  }
  const int tile = req.tile_size() == 0 ? 32 : req.tile_size();
  if (tile < 4 || tile > 256) {
    return Status(StatusCode::INVALID_ARGUMENT, "tile_size: must be in [4, 256], got " + std::to_string(tile));
  }
  Scene scene;
  if (Status s = load_submitted_scene(store_, req, admission, &scene); !s.ok()) return s;
  JobSpec spec;
  if (Status s = job_spec(req, scene, admission, tile, &spec); !s.ok()) return s;
  const int64_t tiles = spec.tiles();
  const int64_t frame_tiles = spec.tiles_per_frame();
  Status refused;
  const JobId id = locked([&]() -> JobId {
    // A job holds a frame's tiles in memory from its first tile on: one that could not start its
    // first frame now is refused rather than queued behind frames nobody has received.
    if (refused = undelivered_limit_locked(); !refused.ok()) return {};
    const int64_t held = scheduler_.tiles_held();
    if (options_.max_resident_tiles > 0 && held + frame_tiles > options_.max_resident_tiles) {
      refused = farm::over_limit(StatusCode::RESOURCE_EXHAUSTED,
                                 "the tiles held in memory with this job's first frame (" + std::to_string(held) +
                                     " of frames already started and not yet received, " + std::to_string(frame_tiles) +
                                     " of one frame of this job; wait for jobs to finish and be delivered)",
                                 held + frame_tiles, "--max-resident-tiles", options_.max_resident_tiles);
      return {};
    }
    JobId id;
    try {
      id = scheduler_.submit(spec);
    } catch (const std::bad_alloc&) {
      // Scheduler::submit builds the job aside and adds it only once whole: nothing is left.
      refused = Status(StatusCode::RESOURCE_EXHAUSTED,
                       "the coordinator ran out of memory building the job's " + std::to_string(tiles) +
                           " tiles: not accepted (lower tessera-server --max-job-tiles or --max-resident-tiles to what "
                           "this machine holds)");
      return {};
    }
    job_status_proto(*scheduler_.job(id), out);
    dispatch_locked();
    return id;
  });
  if (!refused.ok()) return refused;
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
    if (s) job_status_proto(*s, out);
    return s.has_value();
  });
  if (resident) return Status::OK;
  if (auto s = evicted_job(id)) {
    job_status_proto(*s, out);
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
    for (const auto& s : scheduler_.jobs()) job_status_proto(s, out->add_jobs());
    *out->mutable_delivery() = delivery_backlog_locked();
  });
}

// A change a client was told about is durable first (as a submit is): after a crash the job is
// not found running again, or at its old priority. The store's commit window ends at a barrier.
Status Coordinator::durable(Status s, const std::string& what) {
  if (!s.ok() || !jobs_store_) return s;
  if (const std::string err = jobs_store_->barrier().get(); !err.empty()) {
    return Status(StatusCode::UNAVAILABLE, what + " but cannot be stored right now (" + err +
                                               "): it is lost if the coordinator restarts; try again later");
  }
  return s;
}

Status Coordinator::cancel(const std::string& id, v1::JobStatus* out, bool discard_undelivered) {
  return durable(locked([&] {
    switch (scheduler_.cancel(id)) {
      case Scheduler::CancelResult::kUnknownJob:
        return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
      case Scheduler::CancelResult::kAlreadyEnded:
      case Scheduler::CancelResult::kCancelled:
        break;
    }
    job_status_proto(*scheduler_.job(id), out);
    // Its unfinished frames were released with the cancel; with no final frame left to deliver,
    // the job leaves memory now rather than after --retention-hours (`tessera status` answers).
    if (scheduler_.all_acknowledged(id)) {
      evict_locked(id, "cancelled, no frame left to deliver");
    } else if (discard_undelivered) {
      evict_locked(id, "cancelled, its undelivered frames discarded by request");
    }
    return Status::OK;
  }), "job " + id + " is cancelled");
}

Status Coordinator::set_priority(const std::string& id, int priority, v1::JobStatus* out) {
  Status s = set_priority_resident(id, priority, out);
  if (s.error_code() != StatusCode::NOT_FOUND) return s;
  // Left memory: it ended (a cancelled job with nothing to deliver leaves at once).
  if (auto old = evicted_job(id)) {
    return Status(StatusCode::FAILED_PRECONDITION,
                  "job " + id + " has ended (" + job_state_name(old->state) + "): its priority no longer matters");
  }
  return s;
}

Status Coordinator::set_priority_resident(const std::string& id, int priority, v1::JobStatus* out) {
  return durable(locked([&] {
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
    job_status_proto(*scheduler_.job(id), out);
    dispatch_locked();
    return Status::OK;
  }), "job " + id + " has its new priority");
}

Status Coordinator::ack_frame(const std::string& id, int frame) {
  Status s = locked([&] {
    switch (scheduler_.acknowledge_frame(id, frame)) {
      case Scheduler::AckResult::kAcknowledged:
        if (delivered_locked(id)) evict_locked(id, "every frame delivered");
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
  // rendered again, not even after kill -9. Group commit: one fsync per batch.
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

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "coordinator_messages.h"

#include "farm/tile_codec.h"

namespace tessera::server {

namespace v1 = tessera::v1;

namespace {
// The scheduler's clock is steady; the wire speaks Unix time, by the system clock now.
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

void job_status_proto(const JobSnapshot& s, v1::JobStatus* out) {
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
  out->set_tiles_resident(s.tiles_resident);
  if (!s.spec.output.empty()) out->mutable_output()->ParseFromString(s.spec.output);
  out->set_owner(s.spec.owner);
  out->set_waiting_for_memory(s.waiting_for_memory);
}

void worker_proto(const WorkerStats& w, v1::WorkerInfo* p) {
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
  p->set_results_refused(w.refused);
}

void assignment_proto(const Assignment& a, v1::Assignment* p) {
  p->set_lease_id(a.lease.id);
  p->set_deadline_unix_ms(int64_t(to_unix(a.lease.deadline) * 1000));
  p->set_job_id(a.lease.tile.job);
  p->set_bundle_sha256(a.bundle_sha256);
  p->mutable_overrides()->ParseFromString(a.overrides);
  p->set_frame(a.lease.tile.frame);
  p->set_tile_index(a.lease.tile.tile);
  farm::to_proto(a.rect, p->mutable_rect());
  if (!a.plan.empty()) p->set_sample_plan(a.plan);
  if (a.lease.count > 1) {
    p->set_tile_count(a.lease.count);
    p->set_tile_size(a.grid.size());
    p->set_frame_width(a.grid.width());
    p->set_frame_height(a.grid.height());
  }
}

v1::CoordinatorMessage assignment_message(const Assignment& a) {
  v1::CoordinatorMessage m;
  assignment_proto(a, m.mutable_assignment());
  return m;
}

}  // namespace tessera::server

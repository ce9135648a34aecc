// SPDX-License-Identifier: Apache-2.0
// Delivery: who writes each finished frame, and what the coordinator keeps until someone has.
// A watch stream is a spectator (it gets every tile: progress, previews) or a deliverer (it writes
// frames and acknowledges them: `tessera collect`, `tessera watch` with an output). Each frame of a
// job goes to one deliverer at a time under a delivery lease (delivery_leases.h), so deliverers
// never both write a frame, nor both miss it; a deliverer that goes loses its frames to the others.
// Finished frames of jobs with a recorded output are kept, past retention, until delivered
// (undelivered_frames.h). docs/farm.md, "Delivery".
#include <spdlog/spdlog.h>

#include "coordinator.h"
#include "farm/request_limits.h"

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

std::shared_ptr<WatchSink> Coordinator::watcher_locked(const JobId& job, DeliveryLeases::Deliverer d) const {
  auto [b, e] = watchers_.equal_range(job);
  for (auto it = b; it != e; ++it) {
    if (it->second.get() == d) return it->second;
  }
  return nullptr;
}

void Coordinator::send_frame_locked(const JobId& job, const std::shared_ptr<WatchSink>& sink, int frame) {
  for (const auto& [key, output] : scheduler_.finished_tiles(job, frame)) push_tile_locked(job, sink, output.payload);
  if (!scheduler_.frame_final(job, frame)) return;  // the rest follows as it finishes
  v1::WatchJobEvent fd;
  fd.set_frame_done(frame);
  sink->push(fd);
  touched_watchers_.push_back(sink);
  deliveries_.sent_whole(job, frame, Clock::now());
}

void Coordinator::reassign_frames_locked(const JobId& job, const std::vector<int>& frames) {
  for (int frame : frames) {
    if (auto sink = watcher_locked(job, deliveries_.assign(job, frame))) send_frame_locked(job, sink, frame);
  }
}

void Coordinator::expire_deliveries_locked() {
  for (const DeliveryLeases::Moved& m : deliveries_.expire(Clock::now())) {
    const auto secs = std::chrono::duration_cast<std::chrono::seconds>(deliveries_.lease()).count();
    if (!m.to) {
      spdlog::warn(
          "job {} frame {}: its deliverer has not acknowledged it {} s after receiving it whole, and no "
          "other deliverer is attached: it waits for this one",
          m.job, m.frame, secs);
      continue;
    }
    spdlog::warn(
        "job {} frame {}: its deliverer has not acknowledged it {} s after receiving it whole: handed to "
        "another deliverer (the first one's acknowledgement still counts if it comes)",
        m.job, m.frame, secs);
    if (auto sink = watcher_locked(m.job, m.to)) send_frame_locked(m.job, sink, m.frame);
  }
}

void Coordinator::route_tile_locked(const TileKey& key, const TileOutput& out) {
  auto [b, e] = watchers_.equal_range(key.job);
  for (auto it = b; it != e; ++it) {
    if (!deliveries_.delivers(key.job, it->second.get())) push_tile_locked(key.job, it->second, out.payload);
  }
  if (auto sink = watcher_locked(key.job, deliveries_.assign(key.job, key.frame))) {
    push_tile_locked(key.job, sink, out.payload);
  }
}

void Coordinator::route_frame_done_locked(const JobId& job, int frame) {
  v1::WatchJobEvent fd;
  fd.set_frame_done(frame);
  const DeliveryLeases::Deliverer holder = deliveries_.holder(job, frame);
  auto [b, e] = watchers_.equal_range(job);
  for (auto it = b; it != e; ++it) {
    const bool deliverer = deliveries_.delivers(job, it->second.get());
    if (deliverer && it->second.get() != holder) continue;
    it->second->push(fd);
    touched_watchers_.push_back(it->second);
  }
  if (holder) deliveries_.sent_whole(job, frame, Clock::now());
}

bool Coordinator::delivered_locked(const JobId& job) const {
  const JobHeader* h = scheduler_.header(job);
  return h && job_ended(h->state) && scheduler_.all_acknowledged(job);
}

void Coordinator::finish_watchers_locked(const JobId& job, bool all) {
  if (watchers_.find(job) == watchers_.end()) return;  // no stream: no snapshot to build
  auto s = scheduler_.job(job);
  if (!s) return;
  all = all || delivered_locked(job);
  auto [b, e] = watchers_.equal_range(job);
  for (auto it = b; it != e;) {
    if (!all && deliveries_.delivers(job, it->second.get())) {
      ++it;
      continue;
    }
    v1::WatchJobEvent ev;
    job_status_proto(*s, ev.mutable_status());
    it->second->push(ev);
    it->second->finish(Status::OK);
    touched_watchers_.push_back(it->second);
    deliveries_.remove(job, it->second.get());
    it = watchers_.erase(it);
  }
}

void Coordinator::frame_undelivered_locked(const JobId& job, int frame, TimePoint finished) {
  const JobHeader* h = scheduler_.header(job);
  if (!h || h->spec.output.empty()) return;  // nobody said where it goes: retention applies
  uint64_t bytes = 0;
  for (const auto& [key, output] : scheduler_.finished_tiles(job, frame)) {
    if (output.payload) bytes += output.payload->size();
  }
  undelivered_.add(job, frame, bytes, finished);
}

v1::DeliveryBacklog Coordinator::delivery_backlog_locked() const {
  v1::DeliveryBacklog b;
  b.set_frames(int64_t(undelivered_.frames()));
  b.set_bytes(undelivered_.bytes());
  if (auto t = undelivered_.oldest()) b.set_oldest_seconds(std::chrono::duration<double>(Clock::now() - *t).count());
  b.set_limit_bytes(options_.max_undelivered_bytes);
  return b;
}

Status Coordinator::undelivered_limit_locked() const {
  const uint64_t limit = options_.max_undelivered_bytes;
  if (limit == 0 || undelivered_.bytes() < limit) return Status::OK;
  std::string jobs;
  int listed = 0;
  for (const JobId& j : undelivered_.jobs_oldest_first()) {
    if (listed++ == 5) {
      jobs += ", ...";
      break;
    }
    jobs += (jobs.empty() ? "" : ", ") + j;
  }
  return Status(StatusCode::RESOURCE_EXHAUSTED,
                fmt::format("the coordinator holds {} finished frames ({:.1f} GB) that no client has delivered yet, "
                            "at its limit tessera-server --max-undelivered-gb {:.1f}: no new job is accepted until "
                            "they are delivered (`tessera collect`, or `tessera watch JOB` for jobs {}; `tessera cancel JOB --discard` "
                            "drops a job's frames)",
                            undelivered_.frames(), double(undelivered_.bytes()) / 1e9, double(limit) / 1e9, jobs));
}

}  // namespace tessera::server

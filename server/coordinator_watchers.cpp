// SPDX-License-Identifier: Apache-2.0
// Watch streams: a client attached to a job gets its status, every finished tile not yet
// acknowledged, then new tiles and frames as they finish. A stream that falls behind holds its job
// (no new leases) until it has caught up, which bounds the tiles kept in memory for slow clients.
#include "coordinator.h"

#include <spdlog/spdlog.h>

#include <set>

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

Status Coordinator::attach_watcher(const std::string& id, std::shared_ptr<WatchSink> sink, bool deliver) {
  Status st = attach_resident(id, sink, deliver);
  if (st.error_code() != StatusCode::NOT_FOUND) return st;
  // Evicted: ended, and its frames delivered. The final status is all there is to send.
  if (auto old = evicted_job(id)) {
    v1::WatchJobEvent ev;
    job_status_proto(*old, ev.mutable_status());
    sink->push(ev);
    sink->finish(Status::OK);
    sink->pump();
    return Status::OK;
  }
  return st;
}

Status Coordinator::attach_resident(const std::string& id, const std::shared_ptr<WatchSink>& sink, bool deliver) {
  return locked([&] {
    auto s = scheduler_.job(id);
    if (!s) return Status(StatusCode::NOT_FOUND, "no job '" + id + "' on this coordinator");
    v1::WatchJobEvent ev;
    job_status_proto(*s, ev.mutable_status());
    sink->push(ev);
    if (deliver) {
      // A deliverer gets the frames no other deliverer holds, and stays until every finished
      // frame is delivered, by it or by another (a frame another holds comes back if it goes).
      deliveries_.add(id, sink.get());
      std::set<int> frames;  // unacknowledged, with finished tiles
      for (const auto& [key, output] : scheduler_.finished_tiles(id)) frames.insert(key.frame);
      for (int f : frames) {
        if (deliveries_.assign(id, f) == sink.get()) send_frame_locked(id, sink, f);
      }
      if (job_ended(s->state) && delivered_locked(id)) {
        deliveries_.remove(id, sink.get());
        sink->finish(Status::OK);
      } else {
        watchers_.emplace(id, sink);
      }
      touched_watchers_.push_back(sink);
      return Status::OK;
    }
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
    // A deliverer that went (killed, disconnected) loses its frames to the job's other deliverers.
    for (const JobId& job : jobs) {
      if (!deliveries_.delivers(job, sink.get())) continue;
      const std::vector<int> freed = deliveries_.remove(job, sink.get());
      if (!freed.empty()) {
        spdlog::info("job {}: a deliverer went with {} frames undelivered; they go to another deliverer if one is "
                     "attached", job, freed.size());
      }
      reassign_frames_locked(job, freed);
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
  // to it, and its batch builder (client_service.cpp) puts it in a message when its turn comes.
  sink->push_shared(payload);
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

}  // namespace tessera::server

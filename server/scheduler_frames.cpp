// SPDX-License-Identifier: Apache-2.0
// The scheduler's tile queue and frame memory: a job's queue is a range of fresh tiles from a
// cursor plus the tiles given back, and a frame's tile table exists only from its first lease to
// its acknowledgement, under SchedulerOptions::max_job_tiles and max_resident_tiles
// (docs/farm.md, "Memory").
#include "scheduler.h"

#include <algorithm>

namespace tessera::server {

void Scheduler::lay_out_tiles(Job& job) {
  job.spec.tile_size = std::max(1, job.spec.tile_size);
  job.grid = TileGrid(job.spec.width, job.spec.height, job.spec.tile_size);
  job.frames.resize(size_t(std::max(0, job.spec.last_frame - job.spec.first_frame + 1)));
}

void Scheduler::lay_out_frame(Job& job, Frame& frame) {
  if (!frame.tiles.empty()) return;
  frame.tiles.resize(size_t(job.grid.count()));
  job.tiles_resident += int64_t(frame.tiles.size());
  tiles_held_ += int64_t(frame.tiles.size());
}

void Scheduler::drop_frame_tiles(Job& job, Frame& frame) {
  if (frame.tiles.empty()) return;
  job.tiles_resident -= int64_t(frame.tiles.size());
  tiles_held_ -= int64_t(frame.tiles.size());
  std::vector<Tile>().swap(frame.tiles);  // clear() would keep the capacity
}

void Scheduler::memory_freed() {
  if (waiting_for_memory_.empty()) return;
  const std::vector<JobId> waiting(waiting_for_memory_.begin(), waiting_for_memory_.end());
  for (const JobId& id : waiting) update_runnable(*find_job(id));
}

bool Scheduler::fits(const Job& job) const {
  if (job.next_frame >= int(job.frames.size()) || !job.frames[size_t(job.next_frame)].tiles.empty()) return true;
  const int64_t per_frame = job.grid.count();
  return (options_.max_job_tiles <= 0 || job.tiles_resident + per_frame <= options_.max_job_tiles) &&
         (options_.max_resident_tiles <= 0 || tiles_held_ + per_frame <= options_.max_resident_tiles);
}

void Scheduler::settle_cursor(Job& job) {
  const int frames = int(job.frames.size());
  const int per_frame = job.grid.count();
  while (job.next_frame < frames) {
    const Frame& fr = job.frames[size_t(job.next_frame)];
    if (fr.final || fr.released || job.next_tile >= per_frame) {
      ++job.next_frame;
      job.next_tile = 0;
    } else if (!fr.tiles.empty() && fr.tiles[size_t(job.next_tile)].state != TileState::kQueued) {
      ++job.next_tile;
    } else {
      return;
    }
  }
}

std::optional<Scheduler::Span> Scheduler::take_span(Job& job, int max) {
  max = std::max(1, max);
  if (!job.requeued.empty()) {
    // Given back in tile order (end_lease requeues a span's tiles so), so a span given back is
    // handed out again as one.
    const auto [fi, t] = job.requeued.front();
    job.requeued.pop_front();
    Span span{fi, t, 1};
    while (span.count < max && !job.requeued.empty() && job.requeued.front() == std::pair{fi, t + span.count}) {
      job.requeued.pop_front();
      ++span.count;
    }
    return span;
  }
  if (job.fresh <= 0) return std::nullopt;
  settle_cursor(job);
  if (job.next_frame >= int(job.frames.size()) || !fits(job)) return std::nullopt;
  Frame& frame = job.frames[size_t(job.next_frame)];
  lay_out_frame(job, frame);
  // settle_cursor left the cursor on a queued tile; the span runs on while tiles are queued (a
  // restored frame has done tiles among them) and stays within the frame.
  Span span{job.next_frame, job.next_tile, 0};
  const int per_frame = job.grid.count();
  while (span.count < max && job.next_tile < per_frame &&
         frame.tiles[size_t(job.next_tile)].state == TileState::kQueued) {
    ++span.count;
    ++job.next_tile;
    --job.fresh;
  }
  return span;
}

void Scheduler::clear_queue(Job& job) {
  job.requeued.clear();
  job.fresh = 0;
  update_runnable(job);
}

void Scheduler::release_unfinished(Job& job) {
  const int64_t held = job.tiles_resident;
  for (Frame& fr : job.frames) {
    if (fr.final || fr.released) continue;
    fr.done = 0;
    fr.released = true;
    drop_frame_tiles(job, fr);
  }
  clear_queue(job);
  if (job.tiles_resident < held) memory_freed();
}

void Scheduler::update_runnable(Job& job) {
  const bool live = job.state == JobState::kQueued || job.state == JobState::kRunning;
  bool runnable = live && !job.requeued.empty();
  bool waiting = false;
  if (live && !runnable && job.fresh > 0) {
    settle_cursor(job);
    runnable = fits(job);
    waiting = !runnable;
  }
  if (runnable) {
    runnable_.insert(queue_key(job));
  } else {
    runnable_.erase(queue_key(job));
  }
  if (waiting) {
    waiting_for_memory_.insert(job.id);
  } else {
    waiting_for_memory_.erase(job.id);
  }
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// Which tile segments are still needed, for the JobStore (its writer thread, and load() before
// it): the segment holding each stored tile of an unacknowledged frame of a resident job, and
// how many such tiles each segment holds. A segment whose count drops to zero holds nothing a
// client may still ask for, and is deleted. Rows of acknowledged frames keep their (dead)
// location, which is never read, so only the live tiles are counted here.
#pragma once

#include <cstdint>
#include <map>
#include <unordered_map>
#include <utility>
#include <vector>

#include "scheduler.h"

namespace tessera::server {

class SegmentLedger {
 public:
  using FrameKey = std::pair<JobId, int>;

  void clear();
  // The tile's pixels are now in `segment`. The same tile stored again (its row is replaced)
  // leaves its old record dead: that segment loses it.
  void track(const TileKey& key, int64_t segment);
  // The frame's tiles are no longer needed (acknowledged): their segments lose them, and those
  // left with none are appended to `emptied`.
  void release_frame(const FrameKey& frame, std::vector<int64_t>& emptied);
  // The same for every tracked frame of the job (evicted).
  void release_job(const JobId& job, std::vector<int64_t>& emptied);
  // Forgets `segment` when no live tile is left in it: true then, and the caller deletes the
  // file. (A segment can empty and then gain a later tile of the same batch: hence the check.)
  bool forget_if_empty(int64_t segment);
  // Is `segment` counted (it holds a tile read back at start or stored since)?
  bool counts(int64_t segment) const { return segment_live_.count(segment) > 0; }
  // The tracked frames of `job`, in frame order.
  std::vector<FrameKey> frames_of(const JobId& job) const;
  // The segments that releasing `frames` (each once, in this order) would empty; nothing is
  // released.
  std::vector<int64_t> would_empty(const std::vector<FrameKey>& frames) const;

 private:
  std::map<FrameKey, std::map<int, int64_t>> frame_tiles_;  // frame -> tile -> segment
  std::unordered_map<int64_t, int64_t> segment_live_;       // segment -> live tiles in it
};

}  // namespace tessera::server

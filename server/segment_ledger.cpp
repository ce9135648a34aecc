// SPDX-License-Identifier: Apache-2.0
#include "segment_ledger.h"

#include <limits>
#include <set>

namespace tessera::server {

void SegmentLedger::clear() {
  frame_tiles_.clear();
  segment_live_.clear();
}

void SegmentLedger::track(const TileKey& key, int64_t segment) {
  auto& tiles = frame_tiles_[{key.job, key.frame}];
  auto [it, inserted] = tiles.try_emplace(key.tile, segment);
  if (!inserted) {
    // The same tile stored again (INSERT OR REPLACE): its old record is dead.
    --segment_live_[it->second];
    it->second = segment;
  }
  ++segment_live_[segment];
}

void SegmentLedger::release_frame(const FrameKey& frame, std::vector<int64_t>& emptied) {
  auto it = frame_tiles_.find(frame);
  if (it == frame_tiles_.end()) return;
  for (const auto& [tile, seg] : it->second) {
    if (--segment_live_[seg] == 0) emptied.push_back(seg);
  }
  frame_tiles_.erase(it);
}

void SegmentLedger::release_job(const JobId& job, std::vector<int64_t>& emptied) {
  for (const FrameKey& frame : frames_of(job)) release_frame(frame, emptied);
}

bool SegmentLedger::forget_if_empty(int64_t segment) {
  auto it = segment_live_.find(segment);
  if (it == segment_live_.end() || it->second != 0) return false;
  segment_live_.erase(it);
  return true;
}

std::vector<SegmentLedger::FrameKey> SegmentLedger::frames_of(const JobId& job) const {
  std::vector<FrameKey> frames;
  for (auto it = frame_tiles_.lower_bound({job, std::numeric_limits<int>::min()});
       it != frame_tiles_.end() && it->first.first == job; ++it) {
    frames.push_back(it->first);
  }
  return frames;
}

std::vector<int64_t> SegmentLedger::would_empty(const std::vector<FrameKey>& frames) const {
  std::unordered_map<int64_t, int64_t> live = segment_live_;
  std::vector<int64_t> emptied;
  std::set<FrameKey> seen;
  for (const FrameKey& f : frames) {
    if (!seen.insert(f).second) continue;
    auto it = frame_tiles_.find(f);
    if (it == frame_tiles_.end()) continue;
    for (const auto& [tile, seg] : it->second) {
      if (--live[seg] == 0) emptied.push_back(seg);
    }
  }
  return emptied;
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "undelivered_frames.h"

#include <algorithm>
#include <limits>

namespace tessera::server {

void UndeliveredFrames::add(const JobId& job, int frame, uint64_t bytes, TimePoint finished) {
  if (!frames_.try_emplace({job, frame}, Entry{bytes, finished}).second) return;
  by_age_.insert({finished, job});
  bytes_ += bytes;
}

void UndeliveredFrames::remove(const JobId& job, int frame) {
  auto it = frames_.find({job, frame});
  if (it == frames_.end()) return;
  by_age_.erase(by_age_.find({it->second.finished, job}));
  bytes_ -= it->second.bytes;
  frames_.erase(it);
}

void UndeliveredFrames::forget(const JobId& job) {
  auto it = frames_.lower_bound({job, std::numeric_limits<int>::min()});
  while (it != frames_.end() && it->first.first == job) {
    by_age_.erase(by_age_.find({it->second.finished, job}));
    bytes_ -= it->second.bytes;
    it = frames_.erase(it);
  }
}

bool UndeliveredFrames::holds(const JobId& job) const {
  auto it = frames_.lower_bound({job, std::numeric_limits<int>::min()});
  return it != frames_.end() && it->first.first == job;
}

std::optional<TimePoint> UndeliveredFrames::oldest() const {
  if (by_age_.empty()) return std::nullopt;
  return by_age_.begin()->first;
}

std::vector<JobId> UndeliveredFrames::jobs_oldest_first() const {
  std::vector<JobId> out;
  for (const auto& [t, job] : by_age_) {
    if (std::find(out.begin(), out.end(), job) == out.end()) out.push_back(job);
  }
  return out;
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// Frames finished and not yet delivered, of jobs that carry an output (JobSpec::output): what the
// coordinator must keep on disk until a deliverer writes them. Retention never evicts such a job,
// and new jobs are refused once these frames' bytes reach the limit (CoordinatorOptions::
// max_undelivered_bytes), so a farm nobody collects from fills up loudly instead of deleting
// frames. Plain C++: no gRPC, no I/O.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "scheduler.h"

namespace tessera::server {

class UndeliveredFrames {
 public:
  // A frame of the job finished (its tiles' encoded bytes) at `finished`. Adding a frame twice
  // keeps the first.
  void add(const JobId& job, int frame, uint64_t bytes, TimePoint finished);
  void remove(const JobId& job, int frame);  // delivered
  void forget(const JobId& job);             // the job left the coordinator
  bool holds(const JobId& job) const;

  size_t frames() const { return frames_.size(); }
  uint64_t bytes() const { return bytes_; }
  // When the oldest undelivered frame finished; nullopt when there is none.
  std::optional<TimePoint> oldest() const;
  // The jobs holding undelivered frames, oldest frame first (for messages: who to collect).
  std::vector<JobId> jobs_oldest_first() const;

 private:
  struct Entry {
    uint64_t bytes = 0;
    TimePoint finished;
  };
  std::map<std::pair<JobId, int>, Entry> frames_;
  std::multiset<std::pair<TimePoint, JobId>> by_age_;
  uint64_t bytes_ = 0;
};

}  // namespace tessera::server

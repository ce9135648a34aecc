// SPDX-License-Identifier: Apache-2.0
// Delivery leases: which client writes which finished frame. A client that writes frames and
// acknowledges them (a deliverer: `tessera collect`, `tessera watch` with an output) is handed a
// frame's tiles only while it holds the frame, so two deliverers never both write it, nor both
// miss it. A deliverer holds a frame from the first tile it is sent until it acknowledges the
// frame or its stream ends; a frame sent whole and not acknowledged within the lease goes to
// another deliverer of the job (a deliverer stuck on a slow share must not stall the frame), the
// first one's late acknowledgement still counting. Plain C++ like the scheduler: no gRPC, no I/O.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "scheduler.h"

namespace tessera::server {

class DeliveryLeases {
 public:
  using Deliverer = const void*;  // a watch stream; opaque here, never dereferenced

  explicit DeliveryLeases(std::chrono::milliseconds lease) : lease_(lease) {}

  // A deliverer attached to the job (deliverers are preferred in the order they attached).
  void add(const JobId& job, Deliverer d);
  bool delivers(const JobId& job, Deliverer d) const;
  bool has_deliverers(const JobId& job) const;
  // It is gone: returns the frames it held, now held by nobody.
  std::vector<int> remove(const JobId& job, Deliverer d);
  // The deliverer holding the frame; nullptr when none does.
  Deliverer holder(const JobId& job, int frame) const;
  // Gives a frame held by nobody to the job's deliverer holding the fewest frames (of those, the
  // one given a frame longest ago: deliverers that each finish a frame before the next one starts
  // take turns), other than `except`; returns it, or nullptr when the job has no such deliverer.
  Deliverer assign(const JobId& job, int frame, Deliverer except = nullptr);
  // The frame's last tile and its frame_done went to its holder: its lease runs from `now`.
  void sent_whole(const JobId& job, int frame, TimePoint now);
  void acknowledged(const JobId& job, int frame);
  // Frames sent whole more than the lease ago and not acknowledged. Each goes to another
  // deliverer of its job (`to`), or, when there is none, stays with its holder for another lease
  // (`to` nullptr).
  struct Moved {
    JobId job;
    int frame = 0;
    Deliverer from = nullptr;
    Deliverer to = nullptr;
  };
  std::vector<Moved> expire(TimePoint now);
  void forget(const JobId& job);
  std::chrono::milliseconds lease() const { return lease_; }

 private:
  struct Held {
    Deliverer holder = nullptr;
    std::optional<TimePoint> sent;  // when it was sent whole
  };
  struct Job {
    std::vector<Deliverer> deliverers;         // in attach order
    std::map<int, Held> frames;                // frames held, by absolute number
    std::map<Deliverer, uint64_t> last_given;  // when each was last given a frame (0: never)
    uint64_t given = 0;                        // frames given so far
  };
  Deliverer least_loaded(const Job& job, Deliverer except) const;

  std::chrono::milliseconds lease_;
  std::map<JobId, Job> jobs_;
};

}  // namespace tessera::server

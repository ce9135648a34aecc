// SPDX-License-Identifier: Apache-2.0
// The farm as the web monitor's pages see it and steer it: the read-only view (farm_view.h) and
// the two changes a page may make to a job, the same as the CancelJob and SetJobPriority calls.
// The Coordinator implements it; the monitor's routes include this, not coordinator.h.
#pragma once

#include <string>

#include "farm_view.h"

namespace tessera::server {

class FarmControl : public FarmView {
 public:
  // NOT_FOUND for an unknown job (also one evicted from memory); cancelling an ended job
  // answers its status.
  // `discard_undelivered`: its finished frames no client has delivered go too (the job leaves memory).
  virtual grpc::Status cancel(const std::string& id, tessera::v1::JobStatus* out, bool discard_undelivered = false) = 0;
  // NOT_FOUND for an unknown job (also one evicted from memory), FAILED_PRECONDITION for an
  // ended one. The new priority is stored with the job.
  virtual grpc::Status set_priority(const std::string& id, int priority, tessera::v1::JobStatus* out) = 0;
};

}  // namespace tessera::server

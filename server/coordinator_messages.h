// SPDX-License-Identifier: Apache-2.0
// Scheduler values written as protocol messages: what clients read about a job and a worker, and
// the assignment a worker receives. Plain conversions: no state, no lock.
#pragma once

#include "scheduler.h"
#include "tessera/v1/client_service.pb.h"
#include "tessera/v1/worker_service.pb.h"

namespace tessera::server {

// A job as GetJob, ListJobs, the watch stream's status events and the web monitor show it.
void job_status_proto(const JobSnapshot& s, tessera::v1::JobStatus* out);
// A connected worker as ListWorkers shows it (ages measured now).
void worker_proto(const WorkerStats& w, tessera::v1::WorkerInfo* out);
// The message that hands a leased tile to its worker (the deadline in Unix milliseconds).
void assignment_proto(const Assignment& a, tessera::v1::Assignment* out);
tessera::v1::CoordinatorMessage assignment_message(const Assignment& a);

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// How the farm commands word a job: its state and how it is sampled.
#pragma once

#include <string>

#include "tessera/v1/client_service.pb.h"

namespace tessera::cli {

// "queued", "running", "done", "cancelled", "failed" ("unknown" for a state this client does
// not know).
const char* state_name(tessera::v1::JobState s);

// Done, cancelled or failed: the job will not change again.
bool is_final(tessera::v1::JobState s);

// "64 spp" for a uniform job, "target RMSE 0.002 (spp 16-1024)" for a target-error one.
std::string describe_sampling(const tessera::v1::JobStatus& st);

}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
// Downloading a scene bundle from the coordinator (WorkerService.FetchBundle, worker token):
// what workers and the ray server (rays/) do before loading a scene they have not seen.
#pragma once

#include <grpcpp/grpcpp.h>

#include <string>

#include "farm/farm_error.h"
#include "tessera/v1/worker_service.grpc.pb.h"

namespace tessera::farm {

// A failed fetch, keeping the coordinator's status code: NOT_FOUND means the bundle was never
// uploaded, anything else that the coordinator could not be asked.
class FetchError : public FarmError {
 public:
  FetchError(grpc::StatusCode code, const std::string& message) : FarmError(message), code_(code) {}
  grpc::StatusCode code() const { return code_; }

 private:
  grpc::StatusCode code_;
};

// The bundle's bytes (not yet checked against the hash: BundleCache does that). Throws
// FetchError. Deadline 10 minutes: bundles can be large.
std::string fetch_bundle(tessera::v1::WorkerService::Stub& stub, const std::string& sha256);

}  // namespace tessera::farm

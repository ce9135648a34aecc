// SPDX-License-Identifier: Apache-2.0
#include "job_access.h"

namespace tessera::server {

bool authenticated_identity(const std::string& identity) {
  return identity.rfind("cn:", 0) == 0 || identity.rfind("token:", 0) == 0;
}

grpc::Status check_job_access(const std::string& job, const std::string& owner, const Caller& caller,
                              const char* action) {
  if (!authenticated_identity(owner) || caller.admin || caller.identity == owner) return grpc::Status::OK;
  return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                      "job " + job + " belongs to " + owner + ", and you are " + caller.identity + ": only its owner "
                      "or an administrator (tessera-server --admin) may " + action + " it");
}

}  // namespace tessera::server

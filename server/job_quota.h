// SPDX-License-Identifier: Apache-2.0
// Active jobs per client identity, the --max-jobs-per-client limit: the coordinator's own.
#pragma once

#include <grpcpp/grpcpp.h>

#include <map>
#include <mutex>
#include <set>
#include <string>

#include "farm/request_limits.h"

namespace tessera::server {

// Active jobs per client identity (a TLS client certificate's CN, else the peer's address without
// the port). A submission reserves a slot before the scene is parsed, so concurrent submissions
// cannot overshoot; jobs that ended are forgotten the next time that client submits. Each job
// stores its owner, so the count survives a coordinator restart (restore()).
class JobQuota {
 public:
  explicit JobQuota(int max_jobs) : max_(max_jobs) {}
  // Forgets ended jobs (`active(job)` false), then reserves a slot or returns RESOURCE_EXHAUSTED.
  template <class ActiveFn>
  grpc::Status reserve(const std::string& client, ActiveFn active);
  // After the submission: records the job (empty id: it failed) and releases the reservation.
  void settle(const std::string& client, const std::string& job_id);
  // A job of `client` restored from the database at startup.
  void restore(const std::string& client, const std::string& job_id);

 private:
  int max_;
  std::mutex mu_;
  std::map<std::string, std::set<std::string>> jobs_;
  std::map<std::string, int> pending_;
};

template <class ActiveFn>
grpc::Status JobQuota::reserve(const std::string& client, ActiveFn active) {
  std::lock_guard lock(mu_);
  auto& jobs = jobs_[client];
  for (auto it = jobs.begin(); it != jobs.end();) it = active(*it) ? std::next(it) : jobs.erase(it);
  const int64_t n = int64_t(jobs.size()) + pending_[client];
  if (n >= max_) {
    return farm::over_limit(grpc::StatusCode::RESOURCE_EXHAUSTED, "active jobs of client " + client, n + 1,
                            "--max-jobs-per-client", max_);
  }
  ++pending_[client];
  return grpc::Status::OK;
}

}  // namespace tessera::server

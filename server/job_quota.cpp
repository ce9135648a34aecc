// SPDX-License-Identifier: Apache-2.0
#include "job_quota.h"

namespace tessera::server {

void JobQuota::settle(const std::string& client, const std::string& job_id) {
  std::lock_guard lock(mu_);
  if (--pending_[client] <= 0) pending_.erase(client);
  if (!job_id.empty()) jobs_[client].insert(job_id);
}

void JobQuota::restore(const std::string& client, const std::string& job_id) {
  std::lock_guard lock(mu_);
  jobs_[client].insert(job_id);
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// The job store's running totals (JobStore::stats()), apart from the store itself, so that those
// who only read them (the Prometheus metrics, through farm_view.h) need no SQLite.
#pragma once

#include <cstddef>
#include <cstdint>

namespace tessera::server {

struct JobStoreStats {
  int64_t batches = 0, ops = 0, failures = 0;
  size_t queued = 0;
  size_t jobs_to_shed = 0;  // evicted jobs whose rows are not all shed yet
};

}  // namespace tessera::server

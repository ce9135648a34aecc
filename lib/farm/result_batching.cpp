// SPDX-License-Identifier: Apache-2.0
#include "result_batching.h"

#include <algorithm>
#include <cmath>

namespace tessera::farm {

int ResultBatching::depth(int threads, double seconds_per_tile) const {
  threads = std::max(1, threads);
  const int base = 2 * threads;
  if (!(seconds_per_tile > 0) || linger.count() <= 0) return base;
  const double linger_s = std::chrono::duration<double>(linger).count();
  const double extra = std::ceil(double(threads) * linger_s / seconds_per_tile);
  return base + int(std::min(extra, double(std::max(0, max_extra_depth))));
}

size_t ResultBatching::bytes_limit(int64_t coordinator_max_message) const {
  if (coordinator_max_message <= 0) return max_bytes;
  return std::min(max_bytes, size_t(coordinator_max_message) / 2);
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
#include "reconnect_policy.h"

#include <algorithm>
#include <cstdint>

namespace tessera::worker {

std::chrono::milliseconds ReconnectPolicy::next_wait(bool accepted, double jitter) {
  if (accepted) backoff_ = initial_;
  const auto wait = std::chrono::milliseconds(int64_t(double(backoff_.count()) * jitter));
  backoff_ = std::min(max_, backoff_ * 2);
  return wait;
}

}  // namespace tessera::worker

// SPDX-License-Identifier: Apache-2.0
// An optional per-thread log of the exact Embree queries the renderer makes (origin, direction,
// tnear/tfar, mask, the primitive the ray leaves). bench/ray_ceiling replays them with bare
// Embree calls to measure how close the renderer gets to the traversal ceiling. Off (a null
// thread-local pointer, one predictable branch per query) unless a benchmark installs a log.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <vector>

#include "render/hit.h"

namespace tessera {

struct LoggedRay {
  enum class Kind : uint8_t { kCamera, kSecondary, kShadow, kGlassWalk };
  RTCRay ray;  // as passed to Embree (tfar already clipped by the nearest infinite plane)
  PrimRef from;
  Kind kind;
};

struct RayLog {
  std::vector<LoggedRay> rays;
};

// The calling thread's log, or nullptr (the default): set it around a render on one thread.
inline RayLog*& thread_ray_log() {
  static thread_local RayLog* log = nullptr;
  return log;
}

}  // namespace tessera

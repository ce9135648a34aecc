// What makes a ray query meaningless, said per ray and field, so the service can refuse a batch
// with INVALID_ARGUMENT naming the culprit instead of tracing a NaN into a wrong hit.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "rays/world_ray.h"

namespace tessera::rays {

struct RayProblem {
  size_t index = 0;
  std::string field;    // "origin", "direction", "t_min", "t_max"
  std::string message;  // e.g. "ray 17: direction is zero-length"
};

// Largest |coordinate| of an origin: render space is float, and must hold origin minus eye.
inline constexpr double kMaxOrigin = 1e30;

// The first problem of ray `index`, or nothing: non-finite or out-of-range origin, non-finite or
// zero-length direction, NaN, infinite or negative t_min, NaN t_max, t_min > t_max.
std::optional<RayProblem> check_ray(const WorldRay& ray, size_t index);

}  // namespace tessera::rays

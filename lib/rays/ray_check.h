// SPDX-License-Identifier: Apache-2.0
// What makes a ray query meaningless, said per ray and field, so the service can refuse a batch
// with INVALID_ARGUMENT naming the culprit instead of tracing a NaN into a wrong hit.
#pragma once

#include <cstddef>
#include <string>

#include "rays/world_ray.h"

namespace tessera::rays {

// Largest |coordinate| of an origin: render space is float, and must hold origin minus eye.
inline constexpr double kMaxOrigin = 1e30;

// "" for a good ray, else its first problem, naming the ray and the field ("ray 17: direction is
// zero-length"): non-finite or out-of-range origin, non-finite or zero-length direction, NaN,
// infinite or negative t_min, NaN t_max, t_min > t_max. `*field`, when given, is set to the
// field at fault ("origin", "direction", "t_min", "t_max") for a bad ray.
std::string check_ray(const WorldRay& ray, size_t index, std::string* field = nullptr);

}  // namespace tessera::rays

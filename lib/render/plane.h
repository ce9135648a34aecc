// SPDX-License-Identifier: Apache-2.0
// Ray-plane intersection. Planes are infinite, so they live beside Embree (which needs
// bounded geometry), intersected analytically for every ray.
#pragma once

#include <cmath>
#include <limits>

#include "math/vec3.h"

namespace tessera {

// t where o + t d meets the plane through p0 with normal n, or +inf when the ray is parallel
// (including a ray lying in the plane: it grazes, it does not hit) or the plane is behind.
inline double intersect_plane(const Vec3d& o, const Vec3d& d, const Vec3d& p0, const Vec3d& n) {
  const double denom = dot(d, n);
  if (denom == 0.0) return std::numeric_limits<double>::infinity();
  const double t = dot(p0 - o, n) / denom;
  return t >= 0.0 ? t : std::numeric_limits<double>::infinity();
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Ray-sphere intersection that stays accurate for tiny, huge, far and near spheres.
#pragma once

#include <cmath>

#include "math/vec3.h"

namespace tessera {

// Roots of |o + t d - c|^2 = r^2 for unit d, sorted, in double precision. Returns 0 or 2.
// Numerics (Haines et al., "Precision Improvements for Ray/Sphere Intersection", Ray Tracing
// Gems ch. 7): the discriminant is r^2 - |f - (f.d) d|^2 (no b^2 - c cancellation for far
// spheres), and the roots come from q = b + sign(b) sqrt(disc): t0 = c/q, t1 = q, which never
// subtracts nearly equal numbers (the citardauq form). c = (|f| - r)(|f| + r) keeps the
// near-surface case (a huge sphere seen from just above it) accurate.
inline int intersect_sphere(const Vec3d& o, const Vec3d& d, const Vec3d& center, double radius,
                            double t[2]) {
  const Vec3d f = o - center;
  const double b = -dot(f, d);
  const Vec3d l = f + d * b;  // f minus its projection on d: the closest-approach vector
  const double disc = (radius - length(l)) * (radius + length(l));
  if (!(disc >= 0.0)) return 0;
  const double fl = length(f);
  const double c = (fl - radius) * (fl + radius);
  const double q = b + std::copysign(std::sqrt(disc), b);
  if (q == 0.0) {  // the origin is the center and disc == 0: only for radius 0, which is rejected
    t[0] = t[1] = 0.0;
    return 2;
  }
  const double t0 = c / q, t1 = q;
  t[0] = std::min(t0, t1);
  t[1] = std::max(t0, t1);
  return 2;
}

}  // namespace tessera

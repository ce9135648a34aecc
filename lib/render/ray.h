// SPDX-License-Identifier: Apache-2.0
// Rays in render space (camera-relative, float), and spawning secondary rays without
// self-intersection at any scale.
#pragma once

#include <cmath>
#include <limits>

#include "math/next_float.h"
#include "math/vec3.h"

namespace tessera {

// P(t) = o + t d, |d| = 1, t in [0, tmax].
struct Ray {
  Vec3f o;
  Vec3f d;
  float tmax = std::numeric_limits<float>::infinity();
};

// gamma(n) = n u / (1 - n u), u = 2^-24: the classic bound on n rounded float operations
// (Higham; pbrt-v4 "Managing Rounding Error").
constexpr float gamma_bound(int n) {
  constexpr float u = 0x1p-24f;
  return (float(n) * u) / (1.0f - float(n) * u);
}

// pbrt-v4's OffsetRayOrigin: move the (rounded) hit point p off the surface along the
// geometric normal n by the projection of its error box p_err, onto the side that direction w
// leaves through, then round away once more. The offset scales with the point's own error,
// so it is correct at any scene scale, unlike a fixed epsilon.
inline Vec3f offset_ray_origin(const Vec3f& p, const Vec3f& p_err, const Vec3f& n, const Vec3f& w) {
  const float d = dot(abs(n), p_err);
  Vec3f offset = n * d;
  if (dot(w, n) < 0) offset = -offset;
  Vec3f po = p + offset;
  for (int i = 0; i < 3; ++i) {
    if (offset[i] > 0) po[i] = next_float_up(po[i]);
    else if (offset[i] < 0) po[i] = next_float_down(po[i]);
  }
  return po;
}

}  // namespace tessera

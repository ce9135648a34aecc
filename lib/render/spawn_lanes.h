// SPDX-License-Identifier: Apache-2.0
// A packet's surface points that rays leave from, as arrays of components (one lane per ray of
// RenderScene::kPacket): the hit point, its rounding-error bound and the geometric normal facing
// the arriving ray, what render/ray.h's offset_ray_origin needs to spawn a ray robustly. Shared by
// the set-ups of shadow rays (shadow_rays.h) and of reflection and refraction rays
// (secondary_rays.h), which fill it the same way and load it in their SIMD code.
#pragma once

#include "math/vec3.h"

namespace tessera {

inline constexpr int kSpawnLanes = 8;  // RenderScene::kPacket (checked where both are seen)

struct SpawnLanes {
  alignas(32) float px[kSpawnLanes], py[kSpawnLanes], pz[kSpawnLanes];  // Hit::p
  alignas(32) float ex[kSpawnLanes], ey[kSpawnLanes], ez[kSpawnLanes];  // Hit::p_err
  alignas(32) float nx[kSpawnLanes], ny[kSpawnLanes], nz[kSpawnLanes];  // geometric normal, facing the arriving ray

  void set(int i, const Vec3f& p, const Vec3f& p_err, const Vec3f& n_facing) {
    px[i] = p.x, py[i] = p.y, pz[i] = p.z;
    ex[i] = p_err.x, ey[i] = p_err.y, ez[i] = p_err.z;
    nx[i] = n_facing.x, ny[i] = n_facing.y, nz[i] = n_facing.z;
  }
  Vec3f n(int i) const { return {nx[i], ny[i], nz[i]}; }
};

}  // namespace tessera

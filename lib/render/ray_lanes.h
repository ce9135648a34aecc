// SPDX-License-Identifier: Apache-2.0
// A packet's rays as arrays of components (structure of arrays), the form they travel in from
// the camera through the integrator to Embree's packet queries: the SIMD stages read and write
// whole vectors of them, and no stage copies rays between a struct per ray and arrays
// (docs/performance.md, "Packets and SIMD stages": 1-3 % fewer instructions a sample).
#pragma once

#include <cmath>
#include <limits>

#include "render/ray.h"
#include "render/ray_batch.h"

namespace tessera {

inline constexpr int kRayLanes = 8;  // RenderScene::kPacket (checked where both are seen)

struct RayLanes {
  // Lanes a packet does not use still hold finite values (zero at first, then earlier rays):
  // the SIMD stages compute on whole vectors and ignore them.
  alignas(32) float ox[kRayLanes] = {}, oy[kRayLanes] = {}, oz[kRayLanes] = {};
  alignas(32) float dx[kRayLanes] = {}, dy[kRayLanes] = {}, dz[kRayLanes] = {};
  alignas(32) float tmax[kRayLanes] = {};

  Vec3f o(int i) const { return {ox[i], oy[i], oz[i]}; }
  Vec3f d(int i) const { return {dx[i], dy[i], dz[i]}; }
  Ray ray(int i) const { return {o(i), d(i), tmax[i]}; }
  void set(int i, const Vec3f& o, const Vec3f& d, float t = std::numeric_limits<float>::infinity()) {
    ox[i] = o.x, oy[i] = o.y, oz[i] = o.z;
    dx[i] = d.x, dy[i] = d.y, dz[i] = d.z;
    tmax[i] = t;
  }
  void set(int i, const Ray& r) { set(i, r.o, r.d, r.tmax); }
  // Rays given a struct each (tests, the ray service's checks), packed into lanes 0..n-1.
  static RayLanes of(const Ray* rays, int n) {
    RayLanes lanes;
    for (int i = 0; i < n; ++i) lanes.set(i, rays[i]);
    return lanes;
  }
  RayArrays arrays() const { return {ox, oy, oz, dx, dy, dz, tmax}; }
};

// Lane i of `r` becomes the camera ray through the film point (u, v) in [0, 1]^2 of a camera whose
// film point is p0 + du u + dv v from the eye at the origin: normalize(p0 + du u + dv v),
// operation for operation the same wherever a camera ray is made (render/pixel_samples.cpp, the
// lattice sampler's corners and audits), so the same point makes the same bits.
template <class Camera>
[[gnu::always_inline]] inline void set_camera_direction(const Camera& cam, float u, float v, RayLanes* r, int i) {
  const float px = cam.p0.x + cam.du.x * u + cam.dv.x * v;
  const float py = cam.p0.y + cam.du.y * u + cam.dv.y * v;
  const float pz = cam.p0.z + cam.du.z * u + cam.dv.z * v;
  const float len = std::sqrt(px * px + py * py + pz * pz);
  r->dx[i] = px / len;
  r->dy[i] = py / len;
  r->dz[i] = pz / len;
}

}  // namespace tessera

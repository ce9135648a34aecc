// SPDX-License-Identifier: Apache-2.0
// Rays and their nearest hits a batch at a time, as arrays of components (structure of arrays):
// the form SIMD code reads and writes whole vectors of, several rays per instruction. The ray
// service traces its queries this way (RenderScene::intersect_batch); a ray's answer is still
// intersect()'s for that ray alone, bit for bit.
#pragma once

#include <cstddef>
#include <cstdint>

#include "render/hit.h"

namespace tessera {

inline constexpr size_t kRayBatch = 64;  // a multiple of every SIMD width (2, 4, 8 doubles)

// Render-space rays from no surface, as intersect()'s Ray: o + t d, t in (0, tmax].
struct RayBatch {
  alignas(64) float ox[kRayBatch], oy[kRayBatch], oz[kRayBatch];
  alignas(64) float dx[kRayBatch], dy[kRayBatch], dz[kRayBatch];
  alignas(64) float tmax[kRayBatch];
  alignas(64) uint8_t skip[kRayBatch];  // 1: not traced (answered elsewhere): a miss here
};

// A view of rays held as arrays of components: a RayBatch's, or a packet's (render/ray_lanes.h).
// The SIMD arithmetic of render/ray_batch_simd.h reads rays through it, so the ray service's
// batches and the integrator's packets share one implementation without copying rays between
// layouts.
struct RayArrays {
  const float *ox, *oy, *oz;
  const float *dx, *dy, *dz;
  const float* tmax;
  RayArrays(const float* ox_, const float* oy_, const float* oz_, const float* dx_, const float* dy_, const float* dz_,
            const float* tmax_)
      : ox(ox_), oy(oy_), oz(oz_), dx(dx_), dy(dy_), dz(dz_), tmax(tmax_) {}
  RayArrays(const RayBatch& b) : RayArrays(b.ox, b.oy, b.oz, b.dx, b.dy, b.dz, b.tmax) {}  // NOLINT: a view of it
};

// What the ray service reports of a hit, for the rays of a RayBatch.
struct HitBatch {
  // kMiss: no hit. kAnswered: the arrays hold intersect()'s t, p, n, u, v, material and the
  // primitive's source, and the hit has no shading normal (Hit::smooth false). kHit: the hit
  // is in `hit` (a sphere, a mesh with vertex normals, a ray from far away: the rare kinds,
  // answered by the scalar code).
  enum Status : uint8_t { kMiss = 0, kAnswered = 1, kHit = 2 };
  alignas(64) uint8_t status[kRayBatch];
  alignas(64) float t[kRayBatch];
  alignas(64) float px[kRayBatch], py[kRayBatch], pz[kRayBatch];
  alignas(64) float nx[kRayBatch], ny[kRayBatch], nz[kRayBatch];
  alignas(64) float u[kRayBatch], v[kRayBatch];
  alignas(64) uint32_t material[kRayBatch], object[kRayBatch], primitive[kRayBatch];
  Hit hit[kRayBatch];  // where status is kHit
};

}  // namespace tessera

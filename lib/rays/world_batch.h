// SPDX-License-Identifier: Apache-2.0
// World-space rays into a RayBatch and the batch's hits back into world space, a vector of rays
// at a time (Google Highway, picked at run time: world_batch_simd.cpp): lane for lane the
// scalar steps of RayTracer::query() and RayTracer::to_world() (ray_tracer.cpp), in the same
// operations and order, so every answer is bit for bit the scalar one.
#pragma once

#include <cstddef>
#include <cstdint>

#include "math/vec3.h"
#include "rays/world_ray.h"
#include "render/ray_batch.h"

namespace tessera::rays {

// A direction whose length is 1 to within this is taken as given, not normalized again
// (RayTracer's unit_direction(), world_to_render()): a float camera ray replays bit for bit.
inline constexpr double kUnitTolerance = 0x1p-20;

// query()'s common case for rays[0, n) (n <= kRayBatch): the unit direction, the start at
// t_min relative to `origin` (render space's), t_max clipped to float range, rounded to float;
// shift[i] = t_min. A ray that starts beyond `far` (max norm; far > 0) gets skip = 1 and is
// left to the scalar code, which moves its start (query()).
void world_to_render(const WorldRay* rays, size_t n, const Vec3d& origin, double far, RayBatch* out, double* shift);

// to_world() for every lane of a batch that is not skipped and not kHit (those are the scalar
// code's): the WorldHit fields, as arrays, of lanes with status kAnswered whose point is within
// float range (hit = 1: t with the shift added in double where nonzero, the point in world
// space, the normal turned to face the ray), and a miss's defaults (WorldHit{}) for the others.
struct WorldAnswers {
  alignas(64) uint8_t hit[kRayBatch];
  alignas(64) float t[kRayBatch];
  alignas(64) double px[kRayBatch], py[kRayBatch], pz[kRayBatch];
  alignas(64) float nx[kRayBatch], ny[kRayBatch], nz[kRayBatch];
  alignas(64) float nsx[kRayBatch], nsy[kRayBatch], nsz[kRayBatch];
  alignas(64) float u[kRayBatch], v[kRayBatch];
  alignas(64) uint32_t object[kRayBatch], primitive[kRayBatch], material[kRayBatch];
};
void to_world(const HitBatch& hits, const RayBatch& rays, const double* shift, size_t n, const Vec3d& origin,
              WorldAnswers* out);

// Lanes [0, n) of `answers` into the ray service's response arrays (world_ray.h), lane i at index
// offset + i: each asked array written a vector at a time (points, normals and barycentrics
// interleaved in registers), nothing past index offset + n - 1.
void store_hit_columns(const WorldAnswers& answers, size_t n, const HitColumns& out, size_t offset);

}  // namespace tessera::rays

// SPDX-License-Identifier: Apache-2.0
// The arithmetic of RenderScene::intersect_batch (render_scene_batch.cpp) on whole vectors of
// rays: each function is, lane for lane, the scalar code it names, in the same operations and
// the same order (the build contracts nothing into FMAs), so every answer is bit for bit the
// scalar one. Compiled for each SIMD target by Google Highway and picked at run time
// (ray_batch_simd.cpp). Arrays reach at least n rounded up to a multiple of 8 (a RayBatch's
// kRayBatch, a packet's RayLanes): lanes past n are computed and ignored, so they must hold finite
// values.
#pragma once

#include <cstddef>
#include <cstdint>

#include "render/ray_batch.h"

namespace tessera {

// Planes as 6 doubles each (point x, y, z, normal x, y, z) and 2 indices each (material, object).
struct PlaneTable {
  const double* data = nullptr;
  const uint32_t* ids = nullptr;
  size_t count = 0;
};

// nearest_plane(): tp[i] the nearest plane's t in (0, tmax[i]), else tmax[i]; plane[i] its
// index, else -1; tfar[i] the Embree ray's tfar (intersect(): float(tp) where a plane is met,
// else tmax). `exclude`, when given, is the plane each ray leaves (-1: none), never met again
// (nearest_plane()'s `from`); without it, rays from no surface.
void batch_nearest_planes(const RayArrays& rays, size_t n, const PlaneTable& planes, double* tp, int32_t* plane,
                          float* tfar, const int32_t* exclude = nullptr);

// Where select[i] == which: finish_hit()'s point, normal, material and source for triangle
// prim[i] of a bucket (3 unshared vertices per triangle in `positions`, 9 floats; `sources` as
// object, primitive pairs) at Embree's barycentrics u[i], v[i]. Other lanes are left as they are.
struct TriangleTable {
  const float* positions = nullptr;
  const uint32_t* material_ids = nullptr;
  const uint32_t* sources = nullptr;
};
void batch_triangle_hits(const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                         const TriangleTable& triangles, HitBatch* hits);

// Spheres as 5 doubles each (centre x, y, z, radius, then material and object as two 32-bit
// words): RenderScene::Sphere's own layout, read in place.
struct SphereTable {
  const double* data = nullptr;
};

// Where select[i] == which: finish_hit()'s answer on sphere prim[i] (an index into the table)
// at t = hits->t[i] (Embree's tfar): the point recomputed in double from o + d t and projected
// onto the sphere, the outward normal, u = v = 0, the material and the object (primitive 0).
// Other lanes are left as they are.
void batch_sphere_hits(const RayArrays& rays, const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                       const SphereTable& spheres, HitBatch* hits);

// Where select[i] == which: finish_hit()'s answer on plane plane[i] at tp[i]: t, the point
// (o + d tp in double, projected onto the plane), the normal, u = v = 0, the material and the
// object (primitive 0). Other lanes are left as they are.
void batch_plane_hits(const RayArrays& rays, const uint32_t* select, uint32_t which, const double* tp,
                      const int32_t* plane, size_t n, const PlaneTable& planes, HitBatch* hits);
// The same lanes' points alone, rounded to float, into px, py, pz: what an occlusion query reads
// (a plane blocks where its point is within float range).
void batch_plane_points(const RayArrays& rays, const uint32_t* select, uint32_t which, const double* tp,
                        const int32_t* plane, size_t n, const PlaneTable& planes, float* px, float* py, float* pz);

}  // namespace tessera

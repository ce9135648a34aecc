// SPDX-License-Identifier: Apache-2.0
// RenderScene::intersect_batch and any_hit_batch: intersect() and any_hit() for a batch of rays
// from no surface, with the arithmetic around the Embree queries done across rays in SIMD
// (render/ray_batch_simd.h).
//
// Why: for the ray service, tracing a ray is about half Embree's traversal and half the work
// around it (the planes in double, the hit point and normal, the names). Ray by ray that work is
// scalar code in long dependency chains; over arrays of components it is a few vector
// instructions per ray. Triangles without vertex normals, spheres and planes go this way; meshes
// with vertex normals and rays that start far from the geometry are rarer in the queries a
// client sends in bulk, and keep the scalar code.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "render/ray_batch.h"
#include "render/ray_batch_simd.h"
#include "render/render_scene_embree.h"

namespace tessera {

namespace {

// Lane i of a batch as Embree's ray: make_rayhit(...).ray (render_scene_embree.h) for a ray that
// starts near, Embree looking only as far as `tfar` (closer than the nearest plane).
[[gnu::always_inline]] inline void set_embree_ray(const RayBatch& r, size_t i, float tfar, uint32_t mask, RTCRay* q) {
  q->org_x = r.ox[i];
  q->org_y = r.oy[i];
  q->org_z = r.oz[i];
  q->tnear = 0.0f;
  q->dir_x = r.dx[i];
  q->dir_y = r.dy[i];
  q->dir_z = r.dz[i];
  q->time = 0.0f;
  q->tfar = tfar;
  q->mask = mask;
  q->id = 0;
  q->flags = 0;
}

}  // namespace

void RenderScene::intersect_batch(const RayBatch& r, size_t n, HitBatch* h) const {
  alignas(64) double tp[kRayBatch];
  alignas(64) int32_t plane[kRayBatch];
  alignas(64) float tfar[kRayBatch];
  alignas(64) RTCRayHit rh[kRayBatch];
  // What finishes each lane's hit: 0 nothing (a miss, or done here), 1 + k triangle bucket k,
  // 3 a plane, 4 a sphere (the values batch_*() select lanes by).
  constexpr uint32_t kTriangle0 = 1, kPlane = 3, kSphere = 4;
  alignas(64) uint32_t finish[kRayBatch] = {};
  alignas(64) uint32_t prim[kRayBatch] = {};
  bool traced[kRayBatch];
  const PlaneTable planes{plane_table_.data(), plane_ids_.data(), planes_.size()};
  batch_nearest_planes(r, n, planes, tp, plane, tfar);

  for (size_t i = 0; i < n; ++i) {
    traced[i] = false;
    h->status[i] = HitBatch::kMiss;
    if (r.skip[i]) continue;
    if (!starts_near({r.ox[i], r.oy[i], r.oz[i]})) {
      // embree_ray() would move this ray's start (embree_ray_from_far()): intersect() itself.
      const Ray ray{{r.ox[i], r.oy[i], r.oz[i]}, {r.dx[i], r.dy[i], r.dz[i]}, r.tmax[i]};
      if (intersect(ray, PrimRef{}, &h->hit[i])) h->status[i] = HitBatch::kHit;
      continue;
    }
    RTCRayHit& q = rh[i];
    set_embree_ray(r, i, tfar[i], 0xFFFFFFFFu, &q.ray);
    q.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    q.hit.primID = RTC_INVALID_GEOMETRY_ID;
    q.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    traced[i] = true;
  }
  TraceContext ctx;  // read-only during a query: one serves the batch
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = this;
  for (size_t i = 0; i < n; ++i) {
    if (traced[i]) rtcIntersect1(rtc_scene_.get(), &ctx.rtc, &rh[i]);
  }

  // The SIMD finish takes a bucket's triangles by 9 * index in 32-bit lanes, and no shading
  // normals (the service reports them through the scalar path).
  bool simd_bucket[2];
  for (int k = 0; k < 2; ++k) {
    const TriangleBucket& b = triangles_[k];
    simd_bucket[k] = b.normals.empty() && b.material_ids.size() < (size_t(1) << 27);
  }
  // ... and spheres by 10 * index (their 32-bit words).
  const bool simd_spheres = spheres_.size() < (size_t(1) << 27);
  for (size_t i = 0; i < n; ++i) {
    if (!traced[i]) continue;
    const uint32_t g = rh[i].hit.geomID;
    if (g == RTC_INVALID_GEOMETRY_ID) {
      if (plane[i] < 0) continue;  // a miss
      h->status[i] = HitBatch::kAnswered;  // batch_plane_hits() answers
      finish[i] = kPlane;
      continue;
    }
    const int k = g == triangles_[0].geom_id ? 0 : g == triangles_[1].geom_id ? 1 : -1;
    if (k >= 0 && simd_bucket[k]) {
      const uint32_t pid = rh[i].hit.primID;
      const TriangleBucket& b = triangles_[k];
      // The hit triangles' records are cache misses on a large mesh: asked for now, they arrive
      // together while the loop goes on.
      __builtin_prefetch(&b.positions[3 * size_t(pid)]);
      __builtin_prefetch(&b.positions[3 * size_t(pid) + 2]);
      __builtin_prefetch(&b.material_ids[pid]);
      __builtin_prefetch(&b.sources[pid]);
      h->status[i] = HitBatch::kAnswered;  // batch_triangle_hits() answers the rest
      h->t[i] = rh[i].ray.tfar;
      h->u[i] = rh[i].hit.u;
      h->v[i] = rh[i].hit.v;
      prim[i] = pid;
      finish[i] = kTriangle0 + uint32_t(k);
      continue;
    }
    const int s = g == sphere_buckets_[0].geom_id ? 0 : g == sphere_buckets_[1].geom_id ? 1 : -1;
    if (s >= 0 && simd_spheres) {
      h->status[i] = HitBatch::kAnswered;  // batch_sphere_hits() answers the rest
      h->t[i] = rh[i].ray.tfar;
      prim[i] = sphere_buckets_[s].ids[rh[i].hit.primID];
      finish[i] = kSphere;
      continue;
    }
    // A triangle with vertex normals (or a sphere of a scene of over 2^27): finish_hit() itself.
    const Vec3d o(Vec3f(r.ox[i], r.oy[i], r.oz[i])), d(Vec3f(r.dx[i], r.dy[i], r.dz[i]));
    if (finish_hit(o, d, plane[i], tp[i], g, rh[i].hit.primID, rh[i].hit.u, rh[i].hit.v, rh[i].ray.tfar, &h->hit[i])) {
      h->status[i] = HitBatch::kHit;
    }
  }
  for (int k = 0; k < 2; ++k) {
    const TriangleBucket& b = triangles_[k];
    if (b.material_ids.empty() || !simd_bucket[k]) continue;
    static_assert(sizeof(Source) == 2 * sizeof(uint32_t));
    const TriangleTable table{&b.positions[0].x, b.material_ids.data(), &b.sources[0].object};
    batch_triangle_hits(finish, kTriangle0 + uint32_t(k), prim, n, table, h);
  }
  if (!planes_.empty()) batch_plane_hits(r, finish, kPlane, tp, plane, n, planes, h);
  if (!spheres_.empty()) {
    static_assert(sizeof(Sphere) == 5 * sizeof(double) && offsetof(Sphere, center) == 0 && offsetof(Sphere, radius) == 3 * sizeof(double) &&
                  offsetof(Sphere, material) == 4 * sizeof(double) && offsetof(Sphere, object) == 4 * sizeof(double) + 4);
    batch_sphere_hits(r, finish, kSphere, prim, n, SphereTable{&spheres_[0].center.x}, h);
  }
}

void RenderScene::any_hit_batch(const RayBatch& r, size_t n, uint8_t* blocked) const {
  alignas(64) double tp[kRayBatch];
  alignas(64) int32_t plane[kRayBatch];
  alignas(64) float tfar[kRayBatch];
  alignas(64) uint32_t on_plane[kRayBatch] = {};
  const PlaneTable planes{plane_table_.data(), plane_ids_.data(), planes_.size()};
  batch_nearest_planes(r, n, planes, tp, plane, tfar);
  // A plane met first blocks the ray where its point is within float range (any_hit()).
  alignas(64) float px[kRayBatch], py[kRayBatch], pz[kRayBatch];
  if (!planes_.empty()) {
    for (size_t i = 0; i < n; ++i) on_plane[i] = plane[i] >= 0;
    batch_plane_points(r, on_plane, 1, tp, plane, n, planes, px, py, pz);
  }
  TraceContext ctx;  // no glass list: glass blocks like any surface
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = this;
  for (size_t i = 0; i < n; ++i) {
    if (r.skip[i]) continue;
    if (on_plane[i] && std::isfinite(px[i]) && std::isfinite(py[i]) && std::isfinite(pz[i])) {
      blocked[i] = 1;
      continue;
    }
    if (!starts_near({r.ox[i], r.oy[i], r.oz[i]})) {  // embree_ray() would move its start: any_hit() itself
      blocked[i] = any_hit({{r.ox[i], r.oy[i], r.oz[i]}, {r.dx[i], r.dy[i], r.dz[i]}, r.tmax[i]}, PrimRef{});
      continue;
    }
    RTCRay q;
    set_embree_ray(r, i, tfar[i], kOpaqueMask | kGlassMask, &q);
    rtcOccluded1(rtc_scene_.get(), &ctx.rtc, &q);
    blocked[i] = q.tfar < 0.0f;
  }
}

}  // namespace tessera

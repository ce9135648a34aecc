// SPDX-License-Identifier: Apache-2.0
// The Embree side of a RenderScene (render/render_scene_internal.h names these types; they are
// defined here so that its includers need no Embree header): the intersect context our callbacks read,
// the glass crossings a shadow ray collects, and the data each user geometry's callbacks are
// given. For lib/render's own files, and for the benchmarks that replay the renderer's queries
// with bare Embree calls.
#pragma once

#include <cstdint>

#include "render/embree_device.h"
#include "render/render_scene_internal.h"

namespace tessera {

// A glass surface met by a shadow ray (collected during one occlusion query).
struct RenderScene::GlassHit {
  float t;
  uint32_t material;
};

struct RenderScene::GlassHits {
  static constexpr int kMax = 32;
  int count = 0;
  bool overflow = false;
  GlassHit hits[kMax];

  void add(float t, uint32_t material) {
    if (count == kMax) {
      overflow = true;
      return;
    }
    hits[count++] = {t, material};
  }
};

// Sphere `index`'s crossings of a shadow ray in (tnear, tfar), added to *glass: both roots, the
// far one alone for a ray leaving the sphere inward, none for one leaving it outward
// (sphere_geometry.cpp: the occlusion callback's rule, shared with the scan of
// render_scene_scan.cpp).
void add_glass_crossings(const RenderScene::Sphere& s, uint32_t index, const PrimRef& from, const Vec3d& o,
                         const Vec3d& d, float tnear, float tfar, RenderScene::GlassHits* glass);

// Embree's intersect context extended (as in Embree's tutorials) with what our callbacks need.
// `from` is the primitive the ray leaves; for packets, `from_by_id` (if set) gives it per lane,
// indexed by the ray's id, so a lane's result never depends on its packet. `glass` (if set)
// (indexed by ray id too) makes occlusion queries collect glass crossings instead of stopping
// at them.
struct RenderScene::TraceContext {
  RTCIntersectContext rtc;
  const RenderScene* scene = nullptr;
  PrimRef from;
  const PrimRef* from_by_id = nullptr;
  GlassHits* glass = nullptr;

  // The primitive lane i's ray leaves.
  const PrimRef& from_of(RTCRayN* ray, unsigned N, unsigned i) const {
    return from_by_id ? from_by_id[RTCRayN_id(ray, N, i)] : from;
  }
};

// The user data of the watertight test's triangle clusters (cluster_geometry.cpp) and of the
// spheres (sphere_geometry.cpp), one per material class.
struct RenderScene::TriangleGeomData {
  const RenderScene* scene;
  const TriangleBucket* bucket;
  uint32_t bucket_index;  // 0 opaque, 1 glass: PrimRef::geom of its triangles
  uint32_t mask;
};
struct RenderScene::SphereGeomData {
  const RenderScene* scene;
  const SphereBucket* bucket;
};
struct RenderScene::UserGeometryData {
  static_assert(kNoGeometry == RTC_INVALID_GEOMETRY_ID);  // the buckets' "not attached"
  SphereGeomData spheres[2];
  TriangleGeomData triangles[2];
};

// An Embree ray from `ray` (origin, direction) over [tnear, tfar], with no hit yet.
inline RTCRayHit make_rayhit(const Ray& ray, float tnear, float tfar, uint32_t mask) {
  RTCRayHit rh;
  rh.ray.org_x = ray.o.x;
  rh.ray.org_y = ray.o.y;
  rh.ray.org_z = ray.o.z;
  rh.ray.dir_x = ray.d.x;
  rh.ray.dir_y = ray.d.y;
  rh.ray.dir_z = ray.d.z;
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.time = 0.0f;
  rh.ray.mask = mask;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

}  // namespace tessera

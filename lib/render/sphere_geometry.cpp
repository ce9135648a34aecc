// SPDX-License-Identifier: Apache-2.0
// Analytic spheres as Embree user geometry: the roots found in double (render/sphere.h), the
// sphere a ray leaves excluded exactly.
#include <cmath>
#include <cstdint>
#include <limits>

#include "render/render_scene_embree.h"
#include "render/sphere.h"
#include "render/sphere_roots.h"
#include "render/user_geometry.h"

namespace tessera {

namespace {

using TraceContext = RenderScene::TraceContext;
using SphereGeomData = RenderScene::SphereGeomData;

Vec3f round_down(const Vec3d& v) {
  Vec3f f(v);
  for (int i = 0; i < 3; ++i) {
    if (double(f[i]) > v[i]) f[i] = std::nextafter(f[i], -std::numeric_limits<float>::infinity());
  }
  return f;
}
Vec3f round_up(const Vec3d& v) {
  Vec3f f(v);
  for (int i = 0; i < 3; ++i) {
    if (double(f[i]) < v[i]) f[i] = std::nextafter(f[i], std::numeric_limits<float>::infinity());
  }
  return f;
}

void sphere_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* data = static_cast<const SphereGeomData*>(args->geometryUserPtr);
  const auto& s = data->scene->spheres()[data->bucket->ids[args->primID]];
  set_padded_bounds(args->bounds_o, round_down(s.center - Vec3d(s.radius)), round_up(s.center + Vec3d(s.radius)),
                    *data->scene);
}

// The nearest acceptable root of sphere `index` for a ray in (tnear, tfar), or -1.
double sphere_root(const RenderScene::Sphere& s, uint32_t index, const PrimRef& from, const Vec3d& o,
                   const Vec3d& d, float tnear, float tfar) {
  int first = 0;
  if (from.kind == PrimRef::Kind::kSphere && from.id == index) {
    // Leaving this sphere's surface: outward it cannot be met again (convex); inward, only
    // the far root is real. Exact, no epsilon. Tested before the roots: every ray leaving a
    // sphere starts inside its box, so Embree calls back for it, and outward rays (reflections,
    // shadow rays) need no roots at all.
    if (dot(d, o - s.center) >= 0) return -1;
    first = 1;
  }
  double t[2];
  if (intersect_sphere(o, d, s.center, s.radius, t) == 0) return -1;
  for (int i = first; i < 2; ++i) {
    const float tf = float(t[i]);
    if (tf > tnear && tf < tfar) return t[i];
  }
  return -1;
}

// A packet of 8 (rtcIntersect8, rtcOccluded8) tests all its lanes at once (render/sphere_roots.h:
// sphere_root()'s arithmetic, lane for lane): t[i] lane i's root or -1. False for other widths
// (single rays), which take the scalar loop.
template <typename Valid>
bool packet_roots(const Valid* valid, unsigned N, RTCRayN* ray, const TraceContext* ctx, const SphereGeomData* data,
                  uint32_t index, const RenderScene::Sphere& s, double t[kSphereLanes]) {
  if (N != unsigned(kSphereLanes)) return false;
  alignas(32) int32_t active[kSphereLanes], leaving[kSphereLanes];
  for (unsigned i = 0; i < N; ++i) {
    active[i] = valid[i] && (RTCRayN_mask(ray, N, i) & data->bucket->mask) ? 1 : 0;
    const PrimRef& from = active[i] ? ctx->from_of(ray, N, i) : PrimRef{};
    leaving[i] = from.kind == PrimRef::Kind::kSphere && from.id == index ? 1 : 0;
  }
  const SphereLanes lanes{&RTCRayN_org_x(ray, N, 0), &RTCRayN_org_y(ray, N, 0), &RTCRayN_org_z(ray, N, 0),
                          &RTCRayN_dir_x(ray, N, 0), &RTCRayN_dir_y(ray, N, 0), &RTCRayN_dir_z(ray, N, 0),
                          &RTCRayN_tnear(ray, N, 0), &RTCRayN_tfar(ray, N, 0), active, leaving};
  sphere_roots(lanes, s.center, s.radius, t);
  return true;
}

void sphere_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* data = static_cast<const SphereGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  const unsigned N = args->N;
  const uint32_t index = data->bucket->ids[args->primID];
  const auto& s = data->scene->spheres()[index];
  double roots[kSphereLanes];
  if (packet_roots(args->valid, N, ray, ctx, data, index, s, roots)) {
    // Lanes are independent: each reads and writes only its own tfar.
    for (unsigned i = 0; i < N; ++i) {
      if (roots[i] < 0) continue;
      const double t = roots[i];
      const Vec3d o(RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i));
      const Vec3d d(RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i));
      record_hit(args, i, float(t), Vec3f(o + d * t - s.center), 0.0f, 0.0f, args->primID);
    }
    return;
  }
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i] || !(RTCRayN_mask(ray, N, i) & data->bucket->mask)) continue;
    const Vec3d o(RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i));
    const Vec3d d(RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i));
    const double t = sphere_root(s, index, ctx->from_of(ray, N, i), o, d, RTCRayN_tnear(ray, N, i),
                                 RTCRayN_tfar(ray, N, i));
    if (t < 0) continue;
    record_hit(args, i, float(t), Vec3f(o + d * t - s.center), 0.0f, 0.0f, args->primID);
  }
}

void sphere_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const SphereGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  RTCRayN* ray = args->ray;
  const unsigned N = args->N;
  const uint32_t index = data->bucket->ids[args->primID];
  const auto& s = data->scene->spheres()[index];
  const bool collecting = ctx->glass && data->bucket->mask == RenderScene::kGlassMask;
  double roots[kSphereLanes];
  if (!collecting && packet_roots(args->valid, N, ray, ctx, data, index, s, roots)) {
    for (unsigned i = 0; i < N; ++i) {
      if (roots[i] >= 0) RTCRayN_tfar(ray, N, i) = -std::numeric_limits<float>::infinity();
    }
    return;
  }
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i] || !(RTCRayN_mask(ray, N, i) & data->bucket->mask)) continue;
    const Vec3d o(RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i));
    const Vec3d d(RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i));
    const PrimRef& from = ctx->from_of(ray, N, i);
    const float tnear = RTCRayN_tnear(ray, N, i), tfar = RTCRayN_tfar(ray, N, i);
    if (collecting) {
      add_glass_crossings(s, index, from, o, d, tnear, tfar, &ctx->glass[RTCRayN_id(ray, N, i)]);
      continue;
    }
    if (sphere_root(s, index, from, o, d, tnear, tfar) >= 0) {
      RTCRayN_tfar(ray, N, i) = -std::numeric_limits<float>::infinity();
    }
  }
}

}  // namespace

void add_glass_crossings(const RenderScene::Sphere& s, uint32_t index, const PrimRef& from, const Vec3d& o,
                         const Vec3d& d, float tnear, float tfar, RenderScene::GlassHits* glass) {
  // Every root in (tnear, tfar), not just the first (the same roots the old crossing-by-crossing
  // walk found, in one traversal); leaving the sphere, as sphere_root().
  int first = 0;
  if (from.kind == PrimRef::Kind::kSphere && from.id == index) {
    if (dot(d, o - s.center) >= 0) return;
    first = 1;
  }
  double t[2];
  if (intersect_sphere(o, d, s.center, s.radius, t) == 0) return;
  for (int k = first; k < 2; ++k) {
    const float tf = float(t[k]);
    if (tf > tnear && tf < tfar) glass->add(tf, s.material);
  }
}

uint32_t attach_spheres(RTCScene scene, SphereGeomData* data) {
  return attach_user_geometry(scene, data->bucket->ids.size(), data, sphere_bounds, sphere_intersect,
                              sphere_occluded, data->bucket->mask);
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// A RenderScene's single-ray queries: the nearest hit (intersect(), its hit finished in
// finish_hit()) and any hit (any_hit()), the infinite planes met in double beside the Embree
// query; and what the scene tells of a primitive. The batch and packet versions are in
// render_scene_batch.cpp and render_scene_packet.cpp, shadow rays in
// render_scene_transmittance.cpp, the build in render_scene_build.cpp.
#include "render/render_scene_internal.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/plane.h"
#include "render/ray_log.h"
#include "render/render_scene_embree.h"
#include "render/shading_normal.h"

namespace tessera {

namespace {

constexpr double kDoubleEps = 0x1p-52;

}  // namespace

RenderScene::RenderScene(const Scene& scene, int frame, RenderOptions options) : options_(options) {
  build(scene, frame);
}

RenderScene::~RenderScene() {
  rtc_scene_.reset();  // before the geometry data its callbacks and shared buffers point into
}

RenderScene::Source RenderScene::source_of(const PrimRef& prim) const {
  switch (prim.kind) {
    case PrimRef::Kind::kTriangle: return triangles_[prim.geom].sources[prim.id];
    case PrimRef::Kind::kSphere: return {spheres_[prim.id].object, 0};
    case PrimRef::Kind::kPlane: return {planes_[prim.id].object, 0};
    case PrimRef::Kind::kNone: break;
  }
  return {};
}

size_t RenderScene::triangle_count() const {
  return triangles_[0].material_ids.size() + triangles_[1].material_ids.size();
}

double RenderScene::nearest_plane(const Vec3d& o, const Vec3d& d, const PrimRef& from, double tmax,
                                  int* which) const {
  double best = tmax;
  *which = -1;
  for (size_t i = 0; i < planes_.size(); ++i) {
    // A ray leaving a plane can never meet the same plane again: exclude it exactly.
    if (from.kind == PrimRef::Kind::kPlane && from.id == i) continue;
    const double t = intersect_plane(o, d, planes_[i].point, planes_[i].normal);
    if (t > 0.0 && t < best) {
      best = t;
      *which = int(i);
    }
  }
  return best;
}

double RenderScene::embree_ray_from_far(const Ray& ray, Ray* out) const {
  const double L = 2.0 * double(bounds_radius_);
  double t_in = 0.0, t_out = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const double o = ray.o[k], d = ray.d[k];
    if (d == 0.0) {
      if (std::abs(o) > L) return -1.0;
      continue;
    }
    const double a = (-L - o) / d, b = (L - o) / d;
    t_in = std::max(t_in, std::min(a, b));
    t_out = std::min(t_out, std::max(a, b));
  }
  if (!(t_in <= t_out) || !(t_in < double(ray.tmax))) return -1.0;
  out->o = Vec3f(Vec3d(ray.o) + Vec3d(ray.d) * t_in);
  out->tmax = float(double(ray.tmax) - t_in);
  return t_in;
}

bool RenderScene::intersect(const Ray& ray, const PrimRef& from, Hit* hit) const {
  const Vec3d o(ray.o), d(ray.d);
  int plane = -1;
  const double tp = nearest_plane(o, d, from, double(ray.tmax), &plane);
  // Embree only needs to look closer than the nearest plane.
  Ray er;
  const double t0 = embree_ray({ray.o, ray.d, plane >= 0 ? float(tp) : ray.tmax}, &er);
  RTCRayHit rh = make_rayhit(er, 0.0f, er.tmax, 0xFFFFFFFFu);
  if (RayLog* log = thread_ray_log()) {  // every ray, queried or not: the log counts the renderer's rays
    log->rays.push_back({rh.ray, from, from.kind == PrimRef::Kind::kNone ? LoggedRay::Kind::kCamera
                                                                         : LoggedRay::Kind::kSecondary});
  }
  if (t0 >= 0.0) {
    TraceContext ctx;
    rtcInitIntersectContext(&ctx.rtc);
    ctx.scene = this;
    ctx.from = from;
    rtcIntersect1(rtc_scene_.get(), &ctx.rtc, &rh);
  }
  const float t = t0 > 0.0 ? float(t0 + double(rh.ray.tfar)) : rh.ray.tfar;
  return finish_hit(o, d, plane, tp, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v, t, hit);
}

bool RenderScene::finish_hit(const Vec3d& o, const Vec3d& d, int plane, double tp, uint32_t g, uint32_t prim_id,
                             float hit_u, float hit_v, float tfar, Hit* hit) const {
  hit->smooth = false;  // set for triangles with vertex normals below
  if (g != RTC_INVALID_GEOMETRY_ID) {
    hit->t = tfar;
    for (int k = 0; k < 2; ++k) {
      if (g == triangles_[k].geom_id) {
        const TriangleBucket& b = triangles_[k];
        const uint32_t pid = prim_id;
        // Buckets store 3 unshared vertices per triangle (indices[3 pid + k] == 3 pid + k, for
        // Embree's own triangles): read them without the dependent load of the index.
        const Vec3f v0 = b.positions[3 * size_t(pid)], v1 = b.positions[3 * size_t(pid) + 1],
                    v2 = b.positions[3 * size_t(pid) + 2];
        const float u = hit_u, v = hit_v, w = 1.0f - u - v;
        // Interpolating the vertices (not o + t d) bounds the error by the vertices' magnitude.
        hit->p = v0 * w + v1 * u + v2 * v;
        hit->p_err = (abs(v0 * w) + abs(v1 * u) + abs(v2 * v)) * gamma_bound(7);
        hit->n = normalize(cross(v1 - v0, v2 - v0));
        hit->material = b.material_ids[pid];
        hit->prim = {PrimRef::Kind::kTriangle, pid, uint32_t(k)};
        hit->u = u;
        hit->v = v;
        if (!b.uvs.empty()) {
          const float* t = &b.uvs[6 * size_t(pid)];
          hit->tex_u = t[0] * w + t[2] * u + t[4] * v;
          hit->tex_v = t[1] * w + t[3] * u + t[5] * v;
        }
        hit->smooth = !b.normals.empty() && interpolate_shading_normal(&b.normals[9 * size_t(pid)], w, u, v, hit->n, &hit->ns);
        return true;
      }
      if (g == sphere_buckets_[k].geom_id) {
        const uint32_t index = sphere_buckets_[k].ids[prim_id];
        const Sphere& s = spheres_[index];
        // Recompute in double and project back onto the sphere (pbrt-v4's re-projection).
        const Vec3d pd = o + d * double(tfar);
        const Vec3d nd = normalize(pd - s.center);
        const Vec3d pr = s.center + nd * s.radius;
        hit->n = Vec3f(nd);
        finish_sphere_hit(index, uint32_t(k), Vec3f(pr), hit);
        return true;
      }
    }
    return false;  // unreachable: every geometry is one of the buckets
  }
  if (plane < 0) return false;
  const Plane& pl = planes_[size_t(plane)];
  Vec3d pd = o + d * tp;
  pd = pd - pl.normal * dot(pd - pl.point, pl.normal);  // project onto the plane
  hit->t = float(tp);
  hit->n = Vec3f(pl.normal);
  finish_plane_hit(plane, Vec3f(pd), hit);
  return true;
}

void RenderScene::make_error_terms() {
  for (const Sphere& sp : spheres_) sphere_err_.push_back(float(4 * kDoubleEps * (max_component(abs(sp.center)) + sp.radius)));
  for (const Plane& pl : planes_) plane_err_.push_back(float(4 * kDoubleEps * max_component(abs(pl.point))));
}

bool RenderScene::any_hit(const Ray& ray, const PrimRef& from) const {
  // The planes exactly as intersect() meets them; one whose point is beyond float range is no hit,
  // and Embree then looks only closer than it, as intersect() does.
  const Vec3d o(ray.o), d(ray.d);
  int plane = -1;
  const double tp = nearest_plane(o, d, from, double(ray.tmax), &plane);
  Hit h;
  if (plane >= 0 && finish_hit(o, d, plane, tp, RTC_INVALID_GEOMETRY_ID, 0, 0.0f, 0.0f, 0.0f, &h) && is_finite(h.p)) {
    return true;
  }
  Ray er;
  if (embree_ray({ray.o, ray.d, plane >= 0 ? float(tp) : ray.tmax}, &er) < 0.0) return false;
  TraceContext ctx;  // no glass list: glass blocks like any surface
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = this;
  ctx.from = from;
  RTCRay r = make_rayhit(er, 0.0f, er.tmax, kOpaqueMask | kGlassMask).ray;
  rtcOccluded1(rtc_scene_.get(), &ctx.rtc, &r);
  return r.tfar < 0.0f;
}

}  // namespace tessera

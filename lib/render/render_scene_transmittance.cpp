// SPDX-License-Identifier: Apache-2.0
// Shadow rays: the fraction of light a ray lets through (RenderScene::transmittance), opaque
// surfaces blocking it and glass surfaces, crossed unrefracted, multiplying in their
// transmittance in order along the ray. The crossings are collected during the one occlusion
// query (the Embree callbacks add them to the TraceContext's GlassHits); a ray that crosses more
// than GlassHits::kMax of them falls back to walking the glass crossing by crossing.
#include <algorithm>
#include <cmath>
#include <limits>

#include "render/plane.h"
#include "render/ray_log.h"
#include "render/render_scene_embree.h"
#include "render/render_scene_internal.h"

namespace tessera {

namespace {

constexpr int kMaxGlassCrossings = 256;

}  // namespace

bool RenderScene::opaque_plane_blocks(const Ray& ray, const PrimRef& from) const {
  const Vec3d o(ray.o), d(ray.d);
  for (const uint32_t i : opaque_planes_) {
    if (from.kind == PrimRef::Kind::kPlane && from.id == i) continue;
    const double t = intersect_plane(o, d, planes_[i].point, planes_[i].normal);
    if (t > 0.0 && t < double(ray.tmax)) return true;
  }
  return false;
}

Rgb RenderScene::transmittance(const Ray& ray, const PrimRef& from) const {
  // Opaque planes first: cheapest.
  if (opaque_plane_blocks(ray, from)) return Rgb(0.0f);
  TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = this;
  ctx.from = from;
  GlassHits glass;
  // With glass in the scene, one traversal over both classes: opaque hits end it, glass
  // crossings are collected (sphere callback, triangle filter) and multiplied in order below.
  // This replaced an occlusion query plus a crossing-by-crossing glass walk (two or more
  // traversals for every unblocked shadow ray).
  if (has_glass_) ctx.glass = &glass;
  Ray er;
  const double t0 = embree_ray(ray, &er);
  RTCRay r = make_rayhit(er, 0.0f, er.tmax, has_glass_ ? kOpaqueMask | kGlassMask : kOpaqueMask).ray;
  if (RayLog* log = thread_ray_log()) log->rays.push_back({r, from, LoggedRay::Kind::kShadow});
  if (t0 >= 0.0) {
    rtcOccluded1(rtc_scene_.get(), &ctx.rtc, &r);
    if (r.tfar < 0.0f) return Rgb(0.0f);
  }
  if (!has_glass_ || !may_cross_glass(glass)) return Rgb(1.0f);
  ctx.glass = nullptr;
  return glass_product(ray, &ctx, &glass);
}

bool RenderScene::may_cross_glass(const GlassHits& hits) const {
  return glass_planes_ || hits.count > 0 || hits.overflow;
}

Rgb RenderScene::glass_product(const Ray& ray, TraceContext* ctx, GlassHits* glass_hits) const {
  const Vec3d o(ray.o), d(ray.d);
  const PrimRef& from = ctx->from;
  GlassHits& glass = *glass_hits;
  // Glass between the point and the light: multiply the crossings in order along the ray, so the
  // product is formed in the same order every time (bit-identical results).
  Rgb T(1.0f);
  for (size_t i = 0; i < planes_.size(); ++i) {
    if ((from.kind == PrimRef::Kind::kPlane && from.id == i) ||
        materials_[planes_[i].material].type != Material::Type::kGlass) {
      continue;
    }
    const double t = intersect_plane(o, d, planes_[i].point, planes_[i].normal);
    if (t > 0.0 && t < double(ray.tmax)) T *= materials_[planes_[i].material].transmittance;
  }
  if (glass.overflow) return glass_transmittance_walk(ray, ctx, T);
  // Embree reports candidates in traversal order: sort by t (ties by material, so the order is
  // total), and count crossings at the same t once, as the walk stepping past each t did.
  std::sort(glass.hits, glass.hits + glass.count, [](const GlassHit& a, const GlassHit& b) {
    return a.t < b.t || (a.t == b.t && a.material < b.material);
  });
  for (int i = 0; i < glass.count; ++i) {
    if (i > 0 && glass.hits[i].t == glass.hits[i - 1].t) continue;
    T *= materials_[glass.hits[i].material].transmittance;
    if (!(T.x > 0 || T.y > 0 || T.z > 0)) break;
  }
  return T;
}

// The crossing-by-crossing walk, kept for rays that cross more than GlassHits::kMax glass surfaces.
Rgb RenderScene::glass_transmittance_walk(const Ray& original, TraceContext* ctx, Rgb T) const {
  Ray ray;
  if (embree_ray(original, &ray) < 0.0) return T;
  float tnear = 0.0f;
  for (int crossing = 0; crossing < kMaxGlassCrossings; ++crossing) {
    RTCRayHit rh = make_rayhit(ray, tnear, ray.tmax, kGlassMask);
    if (RayLog* log = thread_ray_log()) log->rays.push_back({rh.ray, ctx->from, LoggedRay::Kind::kGlassWalk});
    rtcIntersect1(rtc_scene_.get(), &ctx->rtc, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
    uint32_t m = 0;
    if (rh.hit.geomID == triangles_[1].geom_id) m = triangles_[1].material_ids[rh.hit.primID];
    else m = spheres_[sphere_buckets_[1].ids[rh.hit.primID]].material;
    T *= materials_[m].transmittance;
    if (!(T.x > 0 || T.y > 0 || T.z > 0)) break;
    tnear = std::nextafter(rh.ray.tfar, std::numeric_limits<float>::infinity());
  }
  return T;
}

}  // namespace tessera

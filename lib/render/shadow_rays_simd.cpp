// SPDX-License-Identifier: Apache-2.0
// render/shadow_rays.h's set-up for each SIMD target (SSE4, AVX2, AVX-512), compiled by Google
// Highway and picked at run time, as render/triangle_cluster_simd.cpp is. Each expression
// repeats the scalar code it names (integrator.cpp; ray.h's offset_ray_origin; next_float.h;
// shading_normal.h's smooth_light_cosine) operation for operation and in the same order.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/shadow_rays_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <limits>

#include "render/shadow_rays.h"
#include "render/simd_vec3-inl.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using simd3::DF, simd3::V, simd3::M, simd3::V3, simd3::load3, simd3::dot, simd3::sub;
static_assert(kShadowLanes == 8);  // simd3's packet

// offset_ray_origin (render/ray.h) of the lanes' points toward w.
HWY_INLINE V3 offset_origin(DF df, const ShadingPoints& s, size_t i, const V3& w) {
  return simd3::offset_origin(df, load3(df, s.at.px, s.at.py, s.at.pz, i), load3(df, s.at.ex, s.at.ey, s.at.ez, i),
                              load3(df, s.at.nx, s.at.ny, s.at.nz, i), w);
}

// The cosine weight of light from w: dot(n, w) at flat lanes; smooth_light_cosine at smooth ones.
HWY_INLINE V light_cosine(DF df, const ShadingPoints& s, size_t i, const V3& w) {
  const V zero = hn::Zero(df);
  const V cos_g = dot(load3(df, s.at.nx, s.at.ny, s.at.nz, i), w);
  const M smooth = simd3::flagged(df, s.smooth, i);
  if (hn::AllFalse(df, smooth)) return cos_g;
  const V cos_s = dot(load3(df, s.sx, s.sy, s.sz, i), w);
  const V q = hn::Div(cos_g, hn::Mul(cos_s, hn::Load(df, s.g_dot_s + i)));
  const V one = hn::Set(df, 1.0f);
  const V g = hn::IfThenElse(hn::Lt(q, one), q, one);  // std::fmin(1, q): a NaN q gives 1, as fmin does
  const V gg = hn::Mul(g, g);
  const V term = hn::Sub(hn::Add(g, gg), hn::Mul(gg, g));
  const V smooth_cos = hn::IfThenElseZero(hn::And(hn::Gt(cos_g, zero), hn::Gt(cos_s, zero)), hn::Mul(cos_s, term));
  return hn::IfThenElse(smooth, smooth_cos, cos_g);
}

HWY_INLINE void store_ray(DF df, const V3& o, const V3& w, V tmax, V cone, V b, M live, size_t i, ShadowRays* out) {
  simd3::store3(df, o, out->rays.ox, out->rays.oy, out->rays.oz, i);
  simd3::store3(df, w, out->rays.dx, out->rays.dy, out->rays.dz, i);
  hn::Store(tmax, df, out->rays.tmax + i);
  hn::Store(cone, df, out->cone + i);
  hn::Store(b, df, out->b + i);
  simd3::store_flags(df, live, out->live, i);
}

HWY_INLINE M live_lanes(DF df, const ShadingPoints& s, size_t i) { return simd3::flagged(df, s.live, i); }

void PointLightRays(const ShadingPoints& s, const Vec3f& position, const SpotCone* spot, ShadowRays* out) {
  const DF df;
  const V zero = hn::Zero(df);
  const V3 light{hn::Set(df, position.x), hn::Set(df, position.y), hn::Set(df, position.z)};
  for (size_t i = 0; i < size_t(kShadowLanes); i += hn::Lanes(df)) {
    M live = live_lanes(df, s, i);
    // to = position - p; r2 = dot(to, to); w = to / sqrt(r2).
    const V3 to = sub(light, load3(df, s.at.px, s.at.py, s.at.pz, i));
    const V r2 = dot(to, to);
    const V r = hn::Sqrt(r2);
    const V3 w{hn::Div(to.x, r), hn::Div(to.y, r), hn::Div(to.z, r)};
    const V cos_t = light_cosine(df, s, i, w);
    live = hn::And(live, hn::Gt(cos_t, zero));
    V cone = hn::Set(df, 1.0f);
    if (spot) {
      // SpotLight::falloff(-w): s = clamp(dot(axis, -w) * scale + offset, 0, 1); s * s.
      const V3 axis{hn::Set(df, spot->direction.x), hn::Set(df, spot->direction.y), hn::Set(df, spot->direction.z)};
      const V c = hn::Add(hn::Mul(dot(axis, {hn::Neg(w.x), hn::Neg(w.y), hn::Neg(w.z)}), hn::Set(df, spot->scale)),
                          hn::Set(df, spot->offset));
      // A NaN clamps to 0 here and stays NaN in std::clamp: the lane is dropped either way.
      const V cl = hn::Min(hn::Max(c, zero), hn::Set(df, 1.0f));
      cone = hn::Mul(cl, cl);
      live = hn::And(live, hn::Gt(cone, zero));
    }
    const V3 o = offset_origin(df, s, i, w);
    const V3 left = sub(light, o);
    store_ray(df, o, w, hn::Sqrt(dot(left, left)), cone, hn::Div(cos_t, r2), live, i, out);
  }
}

void DirectionalLightRays(const ShadingPoints& s, const Vec3f& toward, ShadowRays* out) {
  const DF df;
  const V3 w{hn::Set(df, toward.x), hn::Set(df, toward.y), hn::Set(df, toward.z)};
  for (size_t i = 0; i < size_t(kShadowLanes); i += hn::Lanes(df)) {
    const V cos_t = light_cosine(df, s, i, w);
    const M live = hn::And(live_lanes(df, s, i), hn::Gt(cos_t, hn::Zero(df)));
    store_ray(df, offset_origin(df, s, i, w), w, hn::Set(df, std::numeric_limits<float>::infinity()),
              hn::Set(df, 1.0f), cos_t, live, i, out);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera {

HWY_EXPORT(PointLightRays);
HWY_EXPORT(DirectionalLightRays);

void point_light_rays(const ShadingPoints& points, const Vec3f& position, const SpotCone* spot, ShadowRays* out) {
  HWY_DYNAMIC_DISPATCH(PointLightRays)(points, position, spot, out);
}

void directional_light_rays(const ShadingPoints& points, const Vec3f& w, ShadowRays* out) {
  HWY_DYNAMIC_DISPATCH(DirectionalLightRays)(points, w, out);
}

}  // namespace tessera
#endif  // HWY_ONCE

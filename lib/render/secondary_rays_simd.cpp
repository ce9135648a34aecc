// SPDX-License-Identifier: Apache-2.0
// render/secondary_rays.h's set-up for each SIMD target (SSE4, AVX2, AVX-512), compiled by Google
// Highway and picked at run time, as render/shadow_rays_simd.cpp is. Each expression repeats the
// scalar code it names (integrator.cpp's plan_secondary for a flat hit; fresnel.h's reflect,
// fresnel_dielectric and refract; vec3.h's normalize; ray.h's offset_ray_origin) operation for
// operation and in the same order.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/secondary_rays_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "render/secondary_rays.h"
#include "render/simd_vec3-inl.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using simd3::DF, simd3::V, simd3::M, simd3::V3, simd3::load3, simd3::dot, simd3::store3;
static_assert(kTurnLanes == 8);  // simd3's packet

void SecondaryRaysLanes(const TurningPoints& s, SecondaryRays* out) {
  const DF df;
  const V zero = hn::Zero(df), one = hn::Set(df, 1.0f);
  for (size_t i = 0; i < size_t(kTurnLanes); i += hn::Lanes(df)) {
    const M live = simd3::flagged(df, s.live, i);
    if (hn::AllFalse(df, live)) {
      simd3::store_flags(df, live, out->reflect, i);
      simd3::store_flags(df, live, out->refract, i);
      continue;
    }
    const V3 p = load3(df, s.at.px, s.at.py, s.at.pz, i), e = load3(df, s.at.ex, s.at.ey, s.at.ez, i);
    const V3 n = load3(df, s.at.nx, s.at.ny, s.at.nz, i), d = load3(df, s.dx, s.dy, s.dz, i);
    const M glass = hn::And(live, simd3::flagged(df, s.glass, i));
    // reflect(d, n) = d - n (2 dot(d, n)), normalized; the spawn toward it.
    const V dn = dot(d, n);
    const V k2 = hn::Mul(hn::Set(df, 2.0f), dn);
    const V3 wr = simd3::normalize({hn::Sub(d.x, hn::Mul(n.x, k2)), hn::Sub(d.y, hn::Mul(n.y, k2)),
                                    hn::Sub(d.z, hn::Mul(n.z, k2))});
    store3(df, simd3::offset_origin(df, p, e, n, wr), out->rox, out->roy, out->roz, i);
    store3(df, wr, out->rdx, out->rdy, out->rdz, i);
    if (hn::AllFalse(df, glass)) {  // mirrors only: a reflection each, no refraction
      simd3::store_flags(df, live, out->reflect, i);
      simd3::store_flags(df, glass, out->refract, i);
      continue;
    }
    // fresnel_dielectric(cos_i, eta_i, eta_t): cos_i = -dot(d, n), clamped to [0, 1] (std::fmax
    // then std::fmin: a NaN becomes 0, as Max(x, 0) gives).
    const V eta_i = hn::Load(df, s.eta_i + i), eta_t = hn::Load(df, s.eta_t + i);
    const V cos_i = hn::Neg(dn);
    const V c = hn::Min(hn::Max(cos_i, zero), one);
    const M matched = hn::Eq(eta_i, eta_t);  // index-matched: R = 0, cos_t = c
    const V eta = hn::Div(eta_i, eta_t);
    const V sin2_t = hn::Mul(hn::Mul(eta, eta), hn::Max(hn::Sub(one, hn::Mul(c, c)), zero));
    const M tir = hn::AndNot(matched, hn::Ge(sin2_t, one));  // total internal reflection: R = 1, cos_t = 0
    const V root = hn::Sqrt(hn::Max(hn::Sub(one, sin2_t), zero));  // only kept where sin2_t < 1
    const V ic = hn::Mul(eta_i, c), tc = hn::Mul(eta_t, c);
    const V it = hn::Mul(eta_i, root), tt = hn::Mul(eta_t, root);
    const V rs = hn::Div(hn::Sub(ic, tt), hn::Add(ic, tt));
    const V rp = hn::Div(hn::Sub(tc, it), hn::Add(tc, it));
    const V fr = hn::Mul(hn::Set(df, 0.5f), hn::Add(hn::Mul(rs, rs), hn::Mul(rp, rp)));
    const V R = hn::IfThenElse(matched, zero, hn::IfThenElse(tir, one, fr));
    const V cos_t = hn::IfThenElse(matched, c, hn::IfThenElse(tir, zero, root));
    // refract(d, n, eta, cos_i, cos_t) = normalize(d eta + n (eta cos_i - cos_t)), cos_i unclamped.
    const V k = hn::Sub(hn::Mul(eta, cos_i), cos_t);
    const V3 wt = simd3::normalize({hn::Add(hn::Mul(d.x, eta), hn::Mul(n.x, k)),
                                    hn::Add(hn::Mul(d.y, eta), hn::Mul(n.y, k)),
                                    hn::Add(hn::Mul(d.z, eta), hn::Mul(n.z, k))});
    store3(df, simd3::offset_origin(df, p, e, n, wt), out->tox, out->toy, out->toz, i);
    store3(df, wt, out->tdx, out->tdy, out->tdz, i);
    hn::Store(R, df, out->R + i);
    // Mirrors reflect; glass reflects where R > 0 and refracts where R < 1 (a NaN R: neither).
    simd3::store_flags(df, hn::Or(hn::AndNot(glass, live), hn::And(glass, hn::Gt(R, zero))), out->reflect, i);
    simd3::store_flags(df, hn::And(glass, hn::Lt(R, one)), out->refract, i);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera {

HWY_EXPORT(SecondaryRaysLanes);

void secondary_rays(const TurningPoints& points, SecondaryRays* out) {
  HWY_DYNAMIC_DISPATCH(SecondaryRaysLanes)(points, out);
}

}  // namespace tessera
#endif  // HWY_ONCE

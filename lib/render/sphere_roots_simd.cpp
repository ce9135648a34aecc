// SPDX-License-Identifier: Apache-2.0
// render/sphere_roots.h for each SIMD target (SSE4, AVX2, AVX-512), compiled by Google Highway and
// picked at run time, as render/triangle_cluster_simd.cpp is. Each expression repeats the scalar
// code it names (sphere.h's intersect_sphere, sphere_geometry.cpp's sphere_root) operation for
// operation; std::min, std::max and std::copysign are written as the comparisons they are, so a
// NaN goes the way it goes in the scalar code.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/sphere_roots_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "render/sphere_roots.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void SphereRoots(const SphereLanes& r, const Vec3d& center, double radius, double* t_out) {
  const hn::CappedTag<double, kSphereLanes> dd;
  const hn::Rebind<float, decltype(dd)> df;
  const hn::Rebind<int32_t, decltype(dd)> di;
  const size_t N = hn::Lanes(dd);
  const auto zero = hn::Zero(dd);
  const auto none = hn::Set(dd, -1.0);
  const auto cx = hn::Set(dd, center.x), cy = hn::Set(dd, center.y), cz = hn::Set(dd, center.z);
  const auto rad = hn::Set(dd, radius);
  auto load = [&](const float* p, size_t i) { return hn::PromoteTo(dd, hn::LoadU(df, p + i)); };
  for (size_t i = 0; i < size_t(kSphereLanes); i += N) {
    const auto active = hn::RebindMask(dd, hn::Ne(hn::PromoteTo(dd, hn::LoadU(di, r.active + i)), zero));
    if (hn::AllFalse(dd, active)) {
      hn::StoreU(none, dd, t_out + i);
      continue;
    }
    const auto leaving = hn::RebindMask(dd, hn::Ne(hn::PromoteTo(dd, hn::LoadU(di, r.leaving + i)), zero));
    const auto ox = load(r.ox, i), oy = load(r.oy, i), oz = load(r.oz, i);
    const auto dx = load(r.dx, i), dy = load(r.dy, i), dz = load(r.dz, i);
    // f = o - center; b = -dot(f, d); l = f + d b; disc = (radius - |l|)(radius + |l|).
    const auto fx = hn::Sub(ox, cx), fy = hn::Sub(oy, cy), fz = hn::Sub(oz, cz);
    // sphere_root(): leaving the sphere outward (dot(d, o - center) >= 0) meets it no more.
    const auto outward = hn::And(leaving, hn::Ge(hn::Add(hn::Add(hn::Mul(dx, fx), hn::Mul(dy, fy)), hn::Mul(dz, fz)), zero));
    const auto b = hn::Neg(hn::Add(hn::Add(hn::Mul(fx, dx), hn::Mul(fy, dy)), hn::Mul(fz, dz)));
    const auto lx = hn::Add(fx, hn::Mul(dx, b)), ly = hn::Add(fy, hn::Mul(dy, b)), lz = hn::Add(fz, hn::Mul(dz, b));
    const auto len_l = hn::Sqrt(hn::Add(hn::Add(hn::Mul(lx, lx), hn::Mul(ly, ly)), hn::Mul(lz, lz)));
    const auto disc = hn::Mul(hn::Sub(rad, len_l), hn::Add(rad, len_l));
    const auto real = hn::AndNot(outward, hn::And(active, hn::Ge(disc, zero)));
    if (hn::AllFalse(dd, real)) {
      hn::StoreU(none, dd, t_out + i);
      continue;
    }
    const auto fl = hn::Sqrt(hn::Add(hn::Add(hn::Mul(fx, fx), hn::Mul(fy, fy)), hn::Mul(fz, fz)));
    const auto c = hn::Mul(hn::Sub(fl, rad), hn::Add(fl, rad));
    const auto q = hn::Add(b, hn::CopySign(hn::Sqrt(disc), b));
    // q == 0: both roots 0 (intersect_sphere's special case).
    const auto q_zero = hn::Eq(q, zero);
    const auto t0 = hn::IfThenElse(q_zero, zero, hn::Div(c, q)), t1 = hn::IfThenElse(q_zero, zero, q);
    const auto lo = hn::IfThenElse(hn::Lt(t1, t0), t1, t0);  // std::min(t0, t1)
    const auto hi = hn::IfThenElse(hn::Lt(t0, t1), t1, t0);  // std::max(t0, t1)
    // The first root within (tnear, tfar), compared as floats; a leaving ray takes only the far one.
    const auto tnear = load(r.tnear, i), tfar = load(r.tfar, i);
    auto within = [&](hn::Vec<decltype(dd)> t) {
      const auto tf = hn::PromoteTo(dd, hn::DemoteTo(df, t));  // float(t), exactly as a double
      return hn::And(hn::Gt(tf, tnear), hn::Lt(tf, tfar));
    };
    const auto take_lo = hn::AndNot(leaving, within(lo));
    const auto take_hi = within(hi);
    auto t = hn::IfThenElse(take_lo, lo, hn::IfThenElse(take_hi, hi, none));
    hn::StoreU(hn::IfThenElse(real, t, none), dd, t_out + i);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera {

HWY_EXPORT(SphereRoots);

void sphere_roots(const SphereLanes& lanes, const Vec3d& center, double radius, double t[kSphereLanes]) {
  HWY_DYNAMIC_DISPATCH(SphereRoots)(lanes, center, radius, t);
}

}  // namespace tessera
#endif  // HWY_ONCE

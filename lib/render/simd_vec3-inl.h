// SPDX-License-Identifier: Apache-2.0
// Vectors of 3D points and directions, one lane per ray, and the robust spawn of render/ray.h's
// offset_ray_origin, for the per-target code of the *_simd.cpp files (Google Highway's "-inl.h"
// convention: included after <hwy/foreach_target.h> and <hwy/highway.h>, once per target, hence
// the toggled include guard). Each function repeats the scalar code it names operation for
// operation and in the same order, with IEEE add, subtract, multiply, divide and square root only
// (the project builds with -ffp-contract=off), so a lane's bits do not depend on the vector width.
#if defined(TESSERA_RENDER_SIMD_VEC3_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef TESSERA_RENDER_SIMD_VEC3_INL_H_
#undef TESSERA_RENDER_SIMD_VEC3_INL_H_
#else
#define TESSERA_RENDER_SIMD_VEC3_INL_H_
#endif

#include <hwy/highway.h>

#include <limits>

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace simd3 {
namespace hn = hwy::HWY_NAMESPACE;

// At most 8 lanes a vector (a packet, RenderScene::kPacket): one vector on AVX2 and AVX-512, two
// on SSE4.
using DF = hn::CappedTag<float, 8>;
using V = hn::Vec<DF>;
using M = hn::Mask<DF>;

struct V3 {
  V x, y, z;
};

HWY_INLINE V3 load3(DF df, const float* x, const float* y, const float* z, size_t i) {
  return {hn::Load(df, x + i), hn::Load(df, y + i), hn::Load(df, z + i)};
}
HWY_INLINE void store3(DF df, const V3& v, float* x, float* y, float* z, size_t i) {
  hn::Store(v.x, df, x + i);
  hn::Store(v.y, df, y + i);
  hn::Store(v.z, df, z + i);
}
// dot() of vec3.h: a.x b.x + a.y b.y + a.z b.z, left to right.
HWY_INLINE V dot(const V3& a, const V3& b) {
  return hn::Add(hn::Add(hn::Mul(a.x, b.x), hn::Mul(a.y, b.y)), hn::Mul(a.z, b.z));
}
HWY_INLINE V3 sub(const V3& a, const V3& b) { return {hn::Sub(a.x, b.x), hn::Sub(a.y, b.y), hn::Sub(a.z, b.z)}; }
// normalize() of vec3.h: v / sqrt(dot(v, v)), a division per component.
HWY_INLINE V3 normalize(const V3& v) {
  const V len = hn::Sqrt(dot(v, v));
  return {hn::Div(v.x, len), hn::Div(v.y, len), hn::Div(v.z, len)};
}

// next_float_up / next_float_down (math/next_float.h).
HWY_INLINE V next_up(DF df, V v) {
  const hn::RebindToUnsigned<DF> du;
  const auto u = hn::BitCast(du, v);
  const auto one = hn::Set(du, 1u);
  auto r = hn::IfThenElse(hn::RebindMask(du, hn::Gt(v, hn::Zero(df))), hn::Add(u, one), hn::Sub(u, one));
  r = hn::IfThenElse(hn::RebindMask(du, hn::Eq(v, hn::Zero(df))), one, r);
  return hn::IfThenElse(hn::Eq(v, hn::Set(df, std::numeric_limits<float>::infinity())), v, hn::BitCast(df, r));
}
HWY_INLINE V next_down(DF df, V v) {
  const hn::RebindToUnsigned<DF> du;
  const auto u = hn::BitCast(du, v);
  const auto one = hn::Set(du, 1u);
  auto r = hn::IfThenElse(hn::RebindMask(du, hn::Gt(v, hn::Zero(df))), hn::Sub(u, one), hn::Add(u, one));
  r = hn::IfThenElse(hn::RebindMask(du, hn::Eq(v, hn::Zero(df))), hn::Set(du, 0x80000001u), r);
  return hn::IfThenElse(hn::Eq(v, hn::Set(df, -std::numeric_limits<float>::infinity())), v, hn::BitCast(df, r));
}

// offset_ray_origin (render/ray.h): the point p with error bounds e, moved along the normal n
// past its error, to the side of w.
HWY_INLINE V3 offset_origin(DF df, const V3& p, const V3& e, const V3& n, const V3& w) {
  const V d = dot({hn::Abs(n.x), hn::Abs(n.y), hn::Abs(n.z)}, e);
  const M flip = hn::Lt(dot(w, n), hn::Zero(df));
  auto axis = [&](V pc, V nc) {
    V offset = hn::Mul(nc, d);
    offset = hn::IfThenElse(flip, hn::Neg(offset), offset);
    const V po = hn::Add(pc, offset);
    const V zero = hn::Zero(df);
    return hn::IfThenElse(hn::Gt(offset, zero), next_up(df, po),
                          hn::IfThenElse(hn::Lt(offset, zero), next_down(df, po), po));
  };
  return {axis(p.x, n.x), axis(p.y, n.y), axis(p.z, n.z)};
}

// The lanes whose int32 flag is non-zero.
HWY_INLINE M flagged(DF df, const int32_t* flags, size_t i) {
  const hn::RebindToSigned<DF> di;
  return hn::RebindMask(df, hn::Ne(hn::Load(di, flags + i), hn::Zero(di)));
}
HWY_INLINE void store_flags(DF df, M m, int32_t* flags, size_t i) {
  const hn::RebindToSigned<DF> di;
  hn::Store(hn::IfThenElseZero(hn::RebindMask(di, m), hn::Set(di, 1)), di, flags + i);
}

}  // namespace simd3
}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#endif  // TESSERA_RENDER_SIMD_VEC3_INL_H_ toggle

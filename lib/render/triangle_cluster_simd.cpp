// SPDX-License-Identifier: Apache-2.0
// intersect_cluster (render/triangle_cluster.h): the watertight test on a cluster's triangles,
// as many at once as the CPU's double-precision vectors hold (2 with SSE4, 4 with AVX2, 8 with
// AVX-512), compiled for each of those targets by Google Highway and picked at run time, so one
// binary (the worker image) uses what the machine has. Highway rather than intrinsics: the same
// source serves every target, and the test file runs each one against the scalar test.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/triangle_cluster_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "render/triangle_cluster.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// The cluster's lanes whose triangle the exact test might accept (bit k for lane k): every lane
// but those this float pass proves it rejects. Most clusters a ray's traversal reaches hold no
// triangle it crosses, and this pass settles them at float width (8 triangles a vector on AVX2,
// where the exact test takes two vectors of doubles and their conversions).
//
// Why it is exact, not a heuristic: the shear is the exact test's, the same float operations on
// the same floats. Each edge function U = x_c y_b - y_c x_b is then formed in float: the two
// products rounded, then their difference. Rounding is monotonic (a <= b gives fl(a) <= fl(b),
// overflow to infinity included), so fl(fl(a) - fl(b)) > 0 implies a > b, and < 0 implies a < b:
// a non-zero float edge function has the exact sign, the sign the exact test's double computes.
// Only a zero (or NaN) says nothing. So a lane with one edge function provably negative and one
// provably positive is one the exact test rejects by its first test; every other lane goes on
// to the exact test, which decides exactly as before: answers are bit for bit unchanged.
template <class DF>
HWY_INLINE uint32_t MaybeCrossedChunk(DF df, const TriangleCluster& c, size_t j, hn::Vec<DF> ox, hn::Vec<DF> oy,
                                         hn::Vec<DF> oz, hn::Vec<DF> sx, hn::Vec<DF> sy, const RayShear& s) {
  auto sheared = [&](int k, hn::Vec<DF>* x, hn::Vec<DF>* y) {
    const auto X = hn::Sub(hn::LoadU(df, &c.v[k][s.kx][j]), ox);
    const auto Y = hn::Sub(hn::LoadU(df, &c.v[k][s.ky][j]), oy);
    const auto Z = hn::Sub(hn::LoadU(df, &c.v[k][s.kz][j]), oz);
    *x = hn::Sub(X, hn::Mul(sx, Z));
    *y = hn::Sub(Y, hn::Mul(sy, Z));
  };
  hn::Vec<DF> ax, ay, bx, by, cx, cy;
  sheared(0, &ax, &ay);
  sheared(1, &bx, &by);
  sheared(2, &cx, &cy);
  const auto U = hn::Sub(hn::Mul(cx, by), hn::Mul(cy, bx));
  const auto V = hn::Sub(hn::Mul(ax, cy), hn::Mul(ay, cx));
  const auto W = hn::Sub(hn::Mul(bx, ay), hn::Mul(by, ax));
  const auto zero = hn::Zero(df);
  const auto neg = hn::Or(hn::Or(hn::Lt(U, zero), hn::Lt(V, zero)), hn::Lt(W, zero));
  const auto pos = hn::Or(hn::Or(hn::Gt(U, zero), hn::Gt(V, zero)), hn::Gt(W, zero));
  uint8_t bits[8] = {};
  hn::StoreMaskBits(df, hn::Not(hn::And(neg, pos)), bits);
  return uint32_t(bits[0]) << j;
}

// At most kSize float lanes a vector: 8 on AVX2 and AVX-512 (one vector a cluster), 4 on SSE4.
HWY_INLINE uint32_t MaybeCrossed(const TriangleCluster& c, const ClusterRay& r) {
  const hn::CappedTag<float, TriangleCluster::kSize> df;
  const size_t N = hn::Lanes(df);
  const RayShear& s = r.s;
  const auto ox = hn::Set(df, r.ox), oy = hn::Set(df, r.oy), oz = hn::Set(df, r.oz);
  const auto sx = hn::Set(df, s.sx), sy = hn::Set(df, s.sy);
  uint32_t maybe = 0;
  for (size_t j = 0; j < size_t(TriangleCluster::kSize); j += N) maybe |= MaybeCrossedChunk(df, c, j, ox, oy, oz, sx, sy, s);
  return maybe;
}

// Line for line the arithmetic of intersect_triangle_watertight, on Lanes(dd) triangles, for the
// lanes the float pass above leaves open.
// `skip()` names the triangle the ray leaves (UINT32_MAX: none); it is asked only when the float
// pass leaves a lane open, which most clusters a ray reaches do not.
template <class Skip>
HWY_INLINE uint32_t IntersectClusterRay(const TriangleCluster& c, const ClusterRay& r, float tnear, float tfar,
                                        const Skip& skip, TriangleHit* hit) {
  // Which lanes the exact test could accept: all but those a float pass proves it rejects.
  uint32_t maybe = MaybeCrossed(c, r);
  maybe &= (1u << c.count) - 1u;
  if (maybe == 0) return 0;  // the common case: nothing below is needed
  // The triangle the ray leaves, looked for only when lanes are still open: one compare of the
  // cluster's triangle indices (unused lanes hold UINT32_MAX, "none", but are closed already).
  {
    const hn::CappedTag<uint32_t, TriangleCluster::kSize> du;
    const auto leaving = hn::Set(du, skip());
    for (size_t j = 0; j < size_t(TriangleCluster::kSize); j += hn::Lanes(du)) {
      uint8_t bits[8] = {};
      hn::StoreMaskBits(du, hn::Eq(hn::LoadU(du, c.tri + j), leaving), bits);
      maybe &= ~(uint32_t(bits[0]) << j);
    }
  }
  if (maybe == 0) return 0;
  const RayShear& s = r.s;
  const hn::ScalableTag<double> dd;
  const hn::Rebind<float, decltype(dd)> df;  // as many floats as dd has doubles
  const size_t N = hn::Lanes(dd);
  const auto ox = hn::Set(df, r.ox), oy = hn::Set(df, r.oy), oz = hn::Set(df, r.oz);
  const auto sx = hn::Set(df, s.sx), sy = hn::Set(df, s.sy), sz = hn::Set(df, s.sz);
  const auto zero = hn::Zero(dd);
  const auto one = hn::Set(dd, 1.0);
  const auto lo = hn::Set(dd, double(tnear)), hi = hn::Set(dd, double(tfar));
  uint32_t mask = 0;
  alignas(64) float t_out[TriangleCluster::kSize], u_out[TriangleCluster::kSize], v_out[TriangleCluster::kSize];
  for (size_t j = 0; j < size_t(TriangleCluster::kSize); j += N) {
    if (((maybe >> j) & ((1u << N) - 1u)) == 0) continue;  // every lane here provably rejected
    // Vertex k sheared into ray space: x, y (float, as the scalar test) and z before scaling.
    auto shear = [&](int k, hn::Vec<decltype(dd)>* x, hn::Vec<decltype(dd)>* y, hn::Vec<decltype(df)>* z) {
      const auto X = hn::Sub(hn::LoadU(df, &c.v[k][s.kx][j]), ox);
      const auto Y = hn::Sub(hn::LoadU(df, &c.v[k][s.ky][j]), oy);
      const auto Z = hn::Sub(hn::LoadU(df, &c.v[k][s.kz][j]), oz);
      *x = hn::PromoteTo(dd, hn::Sub(X, hn::Mul(sx, Z)));
      *y = hn::PromoteTo(dd, hn::Sub(Y, hn::Mul(sy, Z)));
      *z = Z;
    };
    hn::Vec<decltype(dd)> ax, ay, bx, by, cx, cy;
    hn::Vec<decltype(df)> Az, Bz, Cz;
    shear(0, &ax, &ay, &Az);
    shear(1, &bx, &by, &Bz);
    shear(2, &cx, &cy, &Cz);
    // Products of two floats are exact in double; each difference is rounded once.
    const auto U = hn::Sub(hn::Mul(cx, by), hn::Mul(cy, bx));
    const auto V = hn::Sub(hn::Mul(ax, cy), hn::Mul(ay, cx));
    const auto W = hn::Sub(hn::Mul(bx, ay), hn::Mul(by, ax));
    const auto neg = hn::Or(hn::Or(hn::Lt(U, zero), hn::Lt(V, zero)), hn::Lt(W, zero));
    const auto pos = hn::Or(hn::Or(hn::Gt(U, zero), hn::Gt(V, zero)), hn::Gt(W, zero));
    const auto det = hn::Add(hn::Add(U, V), W);
    const auto inside = hn::AndNot(hn::And(neg, pos), hn::Ne(det, zero));
    // Most clusters a ray reaches hold no triangle it crosses: stop before the division.
    if (hn::AllFalse(dd, inside)) continue;
    const auto az = hn::PromoteTo(dd, hn::Mul(sz, Az));
    const auto bz = hn::PromoteTo(dd, hn::Mul(sz, Bz));
    const auto cz = hn::PromoteTo(dd, hn::Mul(sz, Cz));
    const auto inv = hn::Div(one, det);
    const auto tf = hn::DemoteTo(df, hn::Mul(hn::Add(hn::Add(hn::Mul(U, az), hn::Mul(V, bz)), hn::Mul(W, cz)), inv));
    const auto td = hn::PromoteTo(dd, tf);  // exact: compares as the float t does, NaN fails
    const auto ok = hn::And(inside, hn::And(hn::Ge(td, lo), hn::Le(td, hi)));
    uint8_t bits[8] = {};
    hn::StoreMaskBits(dd, ok, bits);
    mask |= uint32_t(bits[0]) << j;
    hn::StoreU(tf, df, t_out + j);
    hn::StoreU(hn::DemoteTo(df, hn::Mul(V, inv)), df, u_out + j);
    hn::StoreU(hn::DemoteTo(df, hn::Mul(W, inv)), df, v_out + j);
  }
  mask &= maybe;
  for (uint32_t m = mask; m != 0; m &= m - 1) {
    const int k = __builtin_ctz(m);
    hit[k] = {t_out[k], u_out[k], v_out[k]};
  }
  return mask;
}

uint32_t IntersectCluster(const TriangleCluster& c, const ClusterRay& r, float tnear, float tfar, uint32_t skip,
                          TriangleHit* hit) {
  return IntersectClusterRay(c, r, tnear, tfar, [skip] { return skip; }, hit);
}

// cluster_ray() of a packet's lanes, as arrays (a ClusterRay is put together only for the lanes
// tested, so that it stays in registers).
struct PacketRays {
  alignas(64) float sx[ClusterPacket::kMaxLanes], sy[ClusterPacket::kMaxLanes], sz[ClusterPacket::kMaxLanes];
  alignas(64) float ox[ClusterPacket::kMaxLanes], oy[ClusterPacket::kMaxLanes], oz[ClusterPacket::kMaxLanes];
  alignas(64) int32_t kx[ClusterPacket::kMaxLanes], ky[ClusterPacket::kMaxLanes], kz[ClusterPacket::kMaxLanes];
};

// Lanes j.. j + Lanes(df) of PacketRays at once: the same float compares and divisions as
// ray_shear(), IEEE-rounded alike in a vector, so the same bits.
template <class DF>
HWY_INLINE void PrepareRays(DF df, const ClusterPacket& p, size_t j, PacketRays* out) {
  const auto dx = hn::LoadU(df, p.dir_x + j), dy = hn::LoadU(df, p.dir_y + j), dz = hn::LoadU(df, p.dir_z + j);
  const auto ox = hn::LoadU(df, p.org_x + j), oy = hn::LoadU(df, p.org_y + j), oz = hn::LoadU(df, p.org_z + j);
  const auto ax = hn::Abs(dx), ay = hn::Abs(dy), az = hn::Abs(dz);
  // ray_shear(): kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2).
  const auto xy = hn::Gt(ax, ay);
  const auto kz0 = hn::And(xy, hn::Gt(ax, az));
  const auto kz1 = hn::AndNot(xy, hn::Gt(ay, az));
  // kz = 0: (kx, ky) = (1, 2); kz = 1: (2, 0); kz = 2: (0, 1); swapped where d[kz] < 0.
  const auto pick = [&](auto a0, auto a1, auto a2) { return hn::IfThenElse(kz0, a0, hn::IfThenElse(kz1, a1, a2)); };
  const auto dkz = pick(dx, dy, dz), dkx0 = pick(dy, dz, dx), dky0 = pick(dz, dx, dy);
  const auto okz = pick(ox, oy, oz), okx0 = pick(oy, oz, ox), oky0 = pick(oz, ox, oy);
  const auto swap = hn::Lt(dkz, hn::Zero(df));
  const auto dkx = hn::IfThenElse(swap, dky0, dkx0), dky = hn::IfThenElse(swap, dkx0, dky0);
  hn::Store(hn::Div(dkx, dkz), df, out->sx + j);
  hn::Store(hn::Div(dky, dkz), df, out->sy + j);
  hn::Store(hn::Div(hn::Set(df, 1.0f), dkz), df, out->sz + j);
  hn::Store(hn::IfThenElse(swap, oky0, okx0), df, out->ox + j);
  hn::Store(hn::IfThenElse(swap, okx0, oky0), df, out->oy + j);
  hn::Store(okz, df, out->oz + j);
  // The axes too, as ints (picked like the floats above, not decoded lane by lane).
  const hn::RebindToSigned<DF> di;
  const auto ipick = [&](int a0, int a1, int a2) {
    return hn::IfThenElse(hn::RebindMask(di, kz0), hn::Set(di, a0),
                          hn::IfThenElse(hn::RebindMask(di, kz1), hn::Set(di, a1), hn::Set(di, a2)));
  };
  const auto kx0 = ipick(1, 2, 0), ky0 = ipick(2, 0, 1);
  const auto iswap = hn::RebindMask(di, swap);
  hn::Store(hn::IfThenElse(iswap, ky0, kx0), di, out->kx + j);
  hn::Store(hn::IfThenElse(iswap, kx0, ky0), di, out->ky + j);
  hn::Store(ipick(0, 1, 2), di, out->kz + j);
}

uint32_t IntersectClusterPacket(const TriangleCluster& c, const ClusterPacket& p, uint32_t* masks,
                                TriangleHit (*hit)[TriangleCluster::kSize]) {
  const hn::CappedTag<float, TriangleCluster::kSize> df;  // at most 8 lanes: one vector on AVX2
  const hn::RebindToSigned<decltype(df)> di;
  const hn::RebindToUnsigned<decltype(df)> du;
  const size_t n = hn::Lanes(df);
  PacketRays rays;
  uint32_t lanes = 0;  // bit i: lane i valid and its ray's mask meets the geometry's
  if (p.N % n == 0) {
    for (size_t j = 0; j < p.N; j += n) {
      const auto valid = hn::Ne(hn::LoadU(di, p.valid + j), hn::Zero(di));
      const auto meets = hn::Ne(hn::And(hn::LoadU(du, p.mask + j), hn::Set(du, p.geom_mask)), hn::Zero(du));
      uint8_t bits[8] = {};
      hn::StoreMaskBits(di, hn::And(valid, hn::RebindMask(di, meets)), bits);
      if (bits[0] == 0) continue;
      lanes |= uint32_t(bits[0]) << j;
      PrepareRays(df, p, j, &rays);
    }
  } else {  // a packet narrower than a vector (Embree's 4-wide on a wider CPU): lane by lane
    for (unsigned i = 0; i < p.N; ++i) {
      if (p.valid[i] == 0 || (p.mask[i] & p.geom_mask) == 0) continue;
      lanes |= 1u << i;
      const ClusterRay r = cluster_ray({p.org_x[i], p.org_y[i], p.org_z[i]}, {p.dir_x[i], p.dir_y[i], p.dir_z[i]});
      rays.sx[i] = r.s.sx, rays.sy[i] = r.s.sy, rays.sz[i] = r.s.sz;
      rays.ox[i] = r.ox, rays.oy[i] = r.oy, rays.oz[i] = r.oz;
      rays.kx[i] = r.s.kx, rays.ky[i] = r.s.ky, rays.kz[i] = r.s.kz;
    }
  }
  uint32_t hit_lanes = 0;
  for (uint32_t m = lanes; m != 0; m &= m - 1) {
    const int i = __builtin_ctz(m);
    const ClusterRay r{{rays.kx[i], rays.ky[i], rays.kz[i], rays.sx[i], rays.sy[i], rays.sz[i]},
                       rays.ox[i], rays.oy[i], rays.oz[i]};
    const auto leaving = [&] { return p.leaving(p.user, unsigned(i)); };
    masks[i] = IntersectClusterRay(c, r, p.tnear[i], p.tfar[i], leaving, hit[i]);
    hit_lanes |= uint32_t(masks[i] != 0) << i;
  }
  return hit_lanes;
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera {

HWY_EXPORT(IntersectCluster);
HWY_EXPORT(IntersectClusterPacket);

uint32_t intersect_cluster(const TriangleCluster& c, const ClusterRay& r, float tnear, float tfar, uint32_t skip,
                           TriangleHit hit[TriangleCluster::kSize]) {
  return HWY_DYNAMIC_DISPATCH(IntersectCluster)(c, r, tnear, tfar, skip, hit);
}

uint32_t intersect_cluster_packet(const TriangleCluster& c, const ClusterPacket& p, uint32_t* masks,
                                  TriangleHit (*hit)[TriangleCluster::kSize]) {
  return HWY_DYNAMIC_DISPATCH(IntersectClusterPacket)(c, p, masks, hit);
}

}  // namespace tessera
#endif  // HWY_ONCE

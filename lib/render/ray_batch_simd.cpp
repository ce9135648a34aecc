// SPDX-License-Identifier: Apache-2.0
// ray_batch_simd.h's functions for each SIMD target (SSE4, AVX2, AVX-512), compiled by Google
// Highway and picked at run time, as render/triangle_cluster_simd.cpp is. Every expression below
// repeats the scalar code it names operation for operation: IEEE arithmetic rounds each operation
// the same way in a vector lane as in a scalar register, so the answers are bit for bit the
// scalar ones (lib/rays/ray_tracer_test.cpp checks every target).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/ray_batch_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "render/ray_batch_simd.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void BatchNearestPlanes(const RayArrays& r, size_t n, const PlaneTable& planes, double* tp_out, int32_t* plane_out,
                        float* tfar_out, const int32_t* exclude) {
  const hn::ScalableTag<double> dd;
  const hn::Rebind<float, decltype(dd)> df;
  const hn::Rebind<int32_t, decltype(dd)> di;
  const size_t N = hn::Lanes(dd);
  const auto zero = hn::Zero(dd);
  for (size_t i = 0; i < n; i += N) {
    const auto ox = hn::PromoteTo(dd, hn::LoadU(df, r.ox + i)), oy = hn::PromoteTo(dd, hn::LoadU(df, r.oy + i)),
               oz = hn::PromoteTo(dd, hn::LoadU(df, r.oz + i));
    const auto dx = hn::PromoteTo(dd, hn::LoadU(df, r.dx + i)), dy = hn::PromoteTo(dd, hn::LoadU(df, r.dy + i)),
               dz = hn::PromoteTo(dd, hn::LoadU(df, r.dz + i));
    auto tp = hn::PromoteTo(dd, hn::LoadU(df, r.tmax + i));
    auto plane = hn::Set(dd, -1.0);
    // The plane a ray leaves, as a double like `plane` (-1: none).
    const auto left = exclude ? hn::PromoteTo(dd, hn::LoadU(di, exclude + i)) : plane;
    for (size_t k = 0; k < planes.count; ++k) {
      const double* q = planes.data + 6 * k;
      const auto px = hn::Set(dd, q[0]), py = hn::Set(dd, q[1]), pz = hn::Set(dd, q[2]);
      const auto nx = hn::Set(dd, q[3]), ny = hn::Set(dd, q[4]), nz = hn::Set(dd, q[5]);
      // intersect_plane(): denom = dot(d, n), t = dot(p0 - o, n) / denom; kept where denom != 0,
      // t > 0 and t < tp (nearest_plane()'s test).
      const auto denom = hn::Add(hn::Add(hn::Mul(dx, nx), hn::Mul(dy, ny)), hn::Mul(dz, nz));
      const auto num = hn::Add(hn::Add(hn::Mul(hn::Sub(px, ox), nx), hn::Mul(hn::Sub(py, oy), ny)),
                               hn::Mul(hn::Sub(pz, oz), nz));
      const auto t = hn::Div(num, denom);
      const auto take = hn::AndNot(hn::Eq(left, hn::Set(dd, double(k))),
                                   hn::And(hn::And(hn::Ne(denom, zero), hn::Gt(t, zero)), hn::Lt(t, tp)));
      tp = hn::IfThenElse(take, t, tp);
      plane = hn::IfThenElse(take, hn::Set(dd, double(k)), plane);
    }
    hn::StoreU(tp, dd, tp_out + i);
    hn::StoreU(hn::DemoteTo(di, plane), di, plane_out + i);
    hn::StoreU(hn::IfThenElse(hn::RebindMask(df, hn::Gt(hn::DemoteTo(di, plane), hn::Set(di, -1))), hn::DemoteTo(df, tp),
                              hn::LoadU(df, r.tmax + i)),
               df, tfar_out + i);
  }
}

void BatchTriangleHits(const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                       const TriangleTable& tri, HitBatch* h) {
  const hn::ScalableTag<float> df;
  const hn::RebindToUnsigned<decltype(df)> du;
  const hn::RebindToSigned<decltype(df)> di;
  const size_t N = hn::Lanes(df);
  for (size_t i = 0; i < n; i += N) {
    const auto sel = hn::Eq(hn::LoadU(du, select + i), hn::Set(du, which));
    if (hn::AllFalse(du, sel)) continue;
    const auto fsel = hn::RebindMask(df, sel);
    // Other lanes read triangle 0: their indices may be anything.
    const auto p = hn::IfThenElseZero(hn::RebindMask(di, sel), hn::BitCast(di, hn::LoadU(du, prim + i)));
    const auto p9 = hn::Add(hn::ShiftLeft<3>(p), p);  // 9 floats a triangle
    auto vertex = [&](int k) { return hn::GatherIndex(df, tri.positions, hn::Add(p9, hn::Set(di, k))); };
    const auto v0x = vertex(0), v0y = vertex(1), v0z = vertex(2);
    const auto v1x = vertex(3), v1y = vertex(4), v1z = vertex(5);
    const auto v2x = vertex(6), v2y = vertex(7), v2z = vertex(8);
    // finish_hit(): w = 1 - u - v; p = v0 w + v1 u + v2 v; n = normalize(cross(v1 - v0, v2 - v0)).
    const auto u = hn::LoadU(df, h->u + i), v = hn::LoadU(df, h->v + i);
    const auto w = hn::Sub(hn::Sub(hn::Set(df, 1.0f), u), v);
    hn::BlendedStore(hn::Add(hn::Add(hn::Mul(v0x, w), hn::Mul(v1x, u)), hn::Mul(v2x, v)), fsel, df, h->px + i);
    hn::BlendedStore(hn::Add(hn::Add(hn::Mul(v0y, w), hn::Mul(v1y, u)), hn::Mul(v2y, v)), fsel, df, h->py + i);
    hn::BlendedStore(hn::Add(hn::Add(hn::Mul(v0z, w), hn::Mul(v1z, u)), hn::Mul(v2z, v)), fsel, df, h->pz + i);
    const auto e1x = hn::Sub(v1x, v0x), e1y = hn::Sub(v1y, v0y), e1z = hn::Sub(v1z, v0z);
    const auto e2x = hn::Sub(v2x, v0x), e2y = hn::Sub(v2y, v0y), e2z = hn::Sub(v2z, v0z);
    const auto cx = hn::Sub(hn::Mul(e1y, e2z), hn::Mul(e1z, e2y));
    const auto cy = hn::Sub(hn::Mul(e1z, e2x), hn::Mul(e1x, e2z));
    const auto cz = hn::Sub(hn::Mul(e1x, e2y), hn::Mul(e1y, e2x));
    const auto len = hn::Sqrt(hn::Add(hn::Add(hn::Mul(cx, cx), hn::Mul(cy, cy)), hn::Mul(cz, cz)));
    hn::BlendedStore(hn::Div(cx, len), fsel, df, h->nx + i);
    hn::BlendedStore(hn::Div(cy, len), fsel, df, h->ny + i);
    hn::BlendedStore(hn::Div(cz, len), fsel, df, h->nz + i);
    const auto p2 = hn::Add(p, p);
    hn::BlendedStore(hn::GatherIndex(du, tri.material_ids, p), sel, du, h->material + i);
    hn::BlendedStore(hn::GatherIndex(du, tri.sources, p2), sel, du, h->object + i);
    hn::BlendedStore(hn::GatherIndex(du, tri.sources, hn::Add(p2, hn::Set(di, 1))), sel, du, h->primitive + i);
  }
}

// The tags of the analytic surfaces' finishes: doubles, and floats and 32-bit indices with as
// many lanes.
struct Tags {
  hn::ScalableTag<double> dd;
  hn::Rebind<float, decltype(dd)> df;
  hn::Rebind<uint32_t, decltype(dd)> du32;
  hn::Rebind<int32_t, decltype(dd)> di32;
  hn::Rebind<uint64_t, decltype(dd)> du64;
  hn::Rebind<int64_t, decltype(dd)> di64;
};

// The lanes from i where select == which, as 32-bit and 64-bit masks.
struct Selected {
  hn::Mask<decltype(Tags::du32)> m32;
  hn::Mask<decltype(Tags::du64)> m64;
};
HWY_INLINE Selected select_lanes(const Tags& g, const uint32_t* select, uint32_t which, size_t i) {
  const auto s = hn::LoadU(g.du32, select + i);
  return {hn::Eq(s, hn::Set(g.du32, which)), hn::Eq(hn::PromoteTo(g.du64, s), hn::Set(g.du64, uint64_t(which)))};
}

// Index k of the selected lanes, 0 elsewhere (other lanes read entry 0: theirs may be anything).
HWY_INLINE hn::Vec<decltype(Tags::di64)> index64(const Tags& g, const Selected& sel, const int32_t* k, size_t i) {
  return hn::IfThenElseZero(hn::RebindMask(g.di64, sel.m64), hn::PromoteTo(g.di64, hn::LoadU(g.di32, k + i)));
}
HWY_INLINE hn::Vec<decltype(Tags::di32)> index32(const Tags& g, const Selected& sel, const int32_t* k, size_t i) {
  return hn::IfThenElseZero(hn::RebindMask(g.di32, sel.m32), hn::LoadU(g.di32, k + i));
}

// finish_hit()'s answer on a sphere or a plane, in the selected lanes: the point and the normal
// (double, rounded to float), u = v = 0, the material and the object, primitive 0.
HWY_INLINE void store_analytic_hit(const Tags& g, const Selected& sel, hn::Vec<decltype(Tags::dd)> px,
                                   hn::Vec<decltype(Tags::dd)> py, hn::Vec<decltype(Tags::dd)> pz,
                                   hn::Vec<decltype(Tags::dd)> nx, hn::Vec<decltype(Tags::dd)> ny,
                                   hn::Vec<decltype(Tags::dd)> nz, hn::Vec<decltype(Tags::du32)> material,
                                   hn::Vec<decltype(Tags::du32)> object, size_t i, HitBatch* h) {
  const auto fsel = hn::RebindMask(g.df, sel.m32);
  hn::BlendedStore(hn::DemoteTo(g.df, px), fsel, g.df, h->px + i);
  hn::BlendedStore(hn::DemoteTo(g.df, py), fsel, g.df, h->py + i);
  hn::BlendedStore(hn::DemoteTo(g.df, pz), fsel, g.df, h->pz + i);
  hn::BlendedStore(hn::DemoteTo(g.df, nx), fsel, g.df, h->nx + i);
  hn::BlendedStore(hn::DemoteTo(g.df, ny), fsel, g.df, h->ny + i);
  hn::BlendedStore(hn::DemoteTo(g.df, nz), fsel, g.df, h->nz + i);
  hn::BlendedStore(hn::Zero(g.df), fsel, g.df, h->u + i);
  hn::BlendedStore(hn::Zero(g.df), fsel, g.df, h->v + i);
  hn::BlendedStore(material, sel.m32, g.du32, h->material + i);
  hn::BlendedStore(object, sel.m32, g.du32, h->object + i);
  hn::BlendedStore(hn::Zero(g.du32), sel.m32, g.du32, h->primitive + i);
}

// o + d t in double for the rays from i.
struct Point64 {
  hn::Vec<decltype(Tags::dd)> x, y, z;
};
HWY_INLINE Point64 along(const Tags& g, const RayArrays& r, hn::Vec<decltype(Tags::dd)> t, size_t i) {
  auto at = [&](const float* o, const float* d) {
    return hn::Add(hn::PromoteTo(g.dd, hn::LoadU(g.df, o + i)), hn::Mul(hn::PromoteTo(g.dd, hn::LoadU(g.df, d + i)), t));
  };
  return {at(r.ox, r.dx), at(r.oy, r.dy), at(r.oz, r.dz)};
}

// finish_hit()'s point on the planes plane[i] of the selected lanes at tp: pd = o + d tp in
// double, pd = pd - n dot(pd - point, n); and the planes' normals.
struct PlanePoint {
  Point64 p;
  hn::Vec<decltype(Tags::dd)> nx, ny, nz;
};
HWY_INLINE PlanePoint plane_point(const Tags& g, const RayArrays& r, const Selected& sel, const int32_t* plane,
                                  hn::Vec<decltype(Tags::dd)> tp, const PlaneTable& planes, size_t i) {
  const auto k = index64(g, sel, plane, i);
  const auto k6 = hn::Add(hn::ShiftLeft<2>(k), hn::ShiftLeft<1>(k));  // 6 doubles a plane
  // One plane (a floor: the usual case) is the same for every lane: no gathers.
  auto field = [&](int f) {
    return planes.count == 1 ? hn::Set(g.dd, planes.data[f])
                             : hn::GatherIndex(g.dd, planes.data, hn::Add(k6, hn::Set(g.di64, f)));
  };
  const auto qx = field(0), qy = field(1), qz = field(2), nx = field(3), ny = field(4), nz = field(5);
  const Point64 p = along(g, r, tp, i);
  const auto s = hn::Add(hn::Add(hn::Mul(hn::Sub(p.x, qx), nx), hn::Mul(hn::Sub(p.y, qy), ny)), hn::Mul(hn::Sub(p.z, qz), nz));
  return {{hn::Sub(p.x, hn::Mul(nx, s)), hn::Sub(p.y, hn::Mul(ny, s)), hn::Sub(p.z, hn::Mul(nz, s))}, nx, ny, nz};
}

void BatchPlaneHits(const RayArrays& r, const uint32_t* select, uint32_t which, const double* tp_in,
                      const int32_t* plane, size_t n, const PlaneTable& planes, HitBatch* h) {
  const Tags g;
  const size_t N = hn::Lanes(g.dd);
  for (size_t i = 0; i < n; i += N) {
    const Selected sel = select_lanes(g, select, which, i);
    if (hn::AllFalse(g.du32, sel.m32)) continue;
    const auto tp = hn::LoadU(g.dd, tp_in + i);
    const PlanePoint q = plane_point(g, r, sel, plane, tp, planes, i);
    hn::BlendedStore(hn::DemoteTo(g.df, tp), hn::RebindMask(g.df, sel.m32), g.df, h->t + i);
    const auto k32 = index32(g, sel, plane, i);
    const auto k2 = hn::Add(k32, k32);  // 2 indices a plane
    store_analytic_hit(g, sel, q.p.x, q.p.y, q.p.z, q.nx, q.ny, q.nz, hn::GatherIndex(g.du32, planes.ids, k2),
                       hn::GatherIndex(g.du32, planes.ids, hn::Add(k2, hn::Set(g.di32, 1))), i, h);
  }
}

void BatchPlanePoints(const RayArrays& r, const uint32_t* select, uint32_t which, const double* tp_in,
                      const int32_t* plane, size_t n, const PlaneTable& planes, float* px, float* py, float* pz) {
  const Tags g;
  const size_t N = hn::Lanes(g.dd);
  for (size_t i = 0; i < n; i += N) {
    const Selected sel = select_lanes(g, select, which, i);
    if (hn::AllFalse(g.du32, sel.m32)) continue;
    const PlanePoint q = plane_point(g, r, sel, plane, hn::LoadU(g.dd, tp_in + i), planes, i);
    const auto fsel = hn::RebindMask(g.df, sel.m32);
    hn::BlendedStore(hn::DemoteTo(g.df, q.p.x), fsel, g.df, px + i);
    hn::BlendedStore(hn::DemoteTo(g.df, q.p.y), fsel, g.df, py + i);
    hn::BlendedStore(hn::DemoteTo(g.df, q.p.z), fsel, g.df, pz + i);
  }
}

void BatchSphereHits(const RayArrays& r, const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                     const SphereTable& spheres, HitBatch* h) {
  const Tags g;
  const size_t N = hn::Lanes(g.dd);
  const auto* index = reinterpret_cast<const int32_t*>(prim);  // sphere indices are < 2^31
  const auto* words = reinterpret_cast<const uint32_t*>(spheres.data);
  for (size_t i = 0; i < n; i += N) {
    const Selected sel = select_lanes(g, select, which, i);
    if (hn::AllFalse(g.du32, sel.m32)) continue;
    const auto k = index64(g, sel, index, i);
    const auto k5 = hn::Add(hn::ShiftLeft<2>(k), k);  // 5 doubles a sphere
    auto field = [&](int f) { return hn::GatherIndex(g.dd, spheres.data, hn::Add(k5, hn::Set(g.di64, f))); };
    const auto cx = field(0), cy = field(1), cz = field(2), radius = field(3);
    // finish_hit(): pd = o + d t; nd = normalize(pd - center); pr = center + nd radius.
    const Point64 p = along(g, r, hn::PromoteTo(g.dd, hn::LoadU(g.df, h->t + i)), i);
    const auto x = hn::Sub(p.x, cx), y = hn::Sub(p.y, cy), z = hn::Sub(p.z, cz);
    const auto len = hn::Sqrt(hn::Add(hn::Add(hn::Mul(x, x), hn::Mul(y, y)), hn::Mul(z, z)));
    const auto nx = hn::Div(x, len), ny = hn::Div(y, len), nz = hn::Div(z, len);
    const auto k32 = index32(g, sel, index, i);
    const auto k10 = hn::Add(hn::ShiftLeft<3>(k32), hn::Add(k32, k32));  // 10 words a sphere
    store_analytic_hit(g, sel, hn::Add(cx, hn::Mul(nx, radius)), hn::Add(cy, hn::Mul(ny, radius)),
                       hn::Add(cz, hn::Mul(nz, radius)), nx, ny, nz,
                       hn::GatherIndex(g.du32, words, hn::Add(k10, hn::Set(g.di32, 8))),
                       hn::GatherIndex(g.du32, words, hn::Add(k10, hn::Set(g.di32, 9))), i, h);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera {

HWY_EXPORT(BatchNearestPlanes);
HWY_EXPORT(BatchTriangleHits);
HWY_EXPORT(BatchPlaneHits);
HWY_EXPORT(BatchPlanePoints);
HWY_EXPORT(BatchSphereHits);

void batch_nearest_planes(const RayArrays& rays, size_t n, const PlaneTable& planes, double* tp, int32_t* plane,
                          float* tfar, const int32_t* exclude) {
  HWY_DYNAMIC_DISPATCH(BatchNearestPlanes)(rays, n, planes, tp, plane, tfar, exclude);
}

void batch_triangle_hits(const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                         const TriangleTable& triangles, HitBatch* hits) {
  HWY_DYNAMIC_DISPATCH(BatchTriangleHits)(select, which, prim, n, triangles, hits);
}

void batch_plane_hits(const RayArrays& rays, const uint32_t* select, uint32_t which, const double* tp,
                      const int32_t* plane, size_t n, const PlaneTable& planes, HitBatch* hits) {
  HWY_DYNAMIC_DISPATCH(BatchPlaneHits)(rays, select, which, tp, plane, n, planes, hits);
}

void batch_plane_points(const RayArrays& rays, const uint32_t* select, uint32_t which, const double* tp,
                        const int32_t* plane, size_t n, const PlaneTable& planes, float* px, float* py, float* pz) {
  HWY_DYNAMIC_DISPATCH(BatchPlanePoints)(rays, select, which, tp, plane, n, planes, px, py, pz);
}

void batch_sphere_hits(const RayArrays& rays, const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                       const SphereTable& spheres, HitBatch* hits) {
  HWY_DYNAMIC_DISPATCH(BatchSphereHits)(rays, select, which, prim, n, spheres, hits);
}

}  // namespace tessera
#endif  // HWY_ONCE

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

void BatchNearestPlanes(const RayBatch& r, size_t n, const PlaneTable& planes, double* tp_out, int32_t* plane_out,
                        float* tfar_out) {
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
      const auto take = hn::And(hn::And(hn::Ne(denom, zero), hn::Gt(t, zero)), hn::Lt(t, tp));
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

void BatchPlaneHits(const RayBatch& r, const uint32_t* select, uint32_t which, const double* tp_in,
                      const int32_t* plane, size_t n, const PlaneTable& planes, HitBatch* h) {
  const hn::ScalableTag<double> dd;
  const hn::Rebind<float, decltype(dd)> df;
  const hn::Rebind<uint32_t, decltype(dd)> du32;
  const hn::Rebind<int32_t, decltype(dd)> di32;
  const hn::Rebind<uint64_t, decltype(dd)> du64;
  const hn::Rebind<int64_t, decltype(dd)> di64;
  const size_t N = hn::Lanes(dd);
  for (size_t i = 0; i < n; i += N) {
    const auto sel32 = hn::Eq(hn::LoadU(du32, select + i), hn::Set(du32, which));
    if (hn::AllFalse(du32, sel32)) continue;
    const auto sel64 = hn::Eq(hn::PromoteTo(du64, hn::LoadU(du32, select + i)), hn::Set(du64, uint64_t(which)));
    const auto k = hn::IfThenElseZero(hn::RebindMask(di64, sel64), hn::PromoteTo(di64, hn::LoadU(di32, plane + i)));
    const auto k6 = hn::Add(hn::ShiftLeft<2>(k), hn::ShiftLeft<1>(k));  // 6 doubles a plane
    // One plane (a floor: the usual case) is the same for every lane: no gathers.
    auto field = [&](int f) {
      return planes.count == 1 ? hn::Set(dd, planes.data[f]) : hn::GatherIndex(dd, planes.data, hn::Add(k6, hn::Set(di64, f)));
    };
    const auto qx = field(0), qy = field(1), qz = field(2), nx = field(3), ny = field(4), nz = field(5);
    const auto tp = hn::LoadU(dd, tp_in + i);
    // finish_hit(): pd = o + d tp; pd = pd - n dot(pd - point, n).
    const auto x = hn::Add(hn::PromoteTo(dd, hn::LoadU(df, r.ox + i)), hn::Mul(hn::PromoteTo(dd, hn::LoadU(df, r.dx + i)), tp));
    const auto y = hn::Add(hn::PromoteTo(dd, hn::LoadU(df, r.oy + i)), hn::Mul(hn::PromoteTo(dd, hn::LoadU(df, r.dy + i)), tp));
    const auto z = hn::Add(hn::PromoteTo(dd, hn::LoadU(df, r.oz + i)), hn::Mul(hn::PromoteTo(dd, hn::LoadU(df, r.dz + i)), tp));
    const auto s = hn::Add(hn::Add(hn::Mul(hn::Sub(x, qx), nx), hn::Mul(hn::Sub(y, qy), ny)), hn::Mul(hn::Sub(z, qz), nz));
    const auto fsel = hn::RebindMask(df, sel32);
    hn::BlendedStore(hn::DemoteTo(df, hn::Sub(x, hn::Mul(nx, s))), fsel, df, h->px + i);
    hn::BlendedStore(hn::DemoteTo(df, hn::Sub(y, hn::Mul(ny, s))), fsel, df, h->py + i);
    hn::BlendedStore(hn::DemoteTo(df, hn::Sub(z, hn::Mul(nz, s))), fsel, df, h->pz + i);
    hn::BlendedStore(hn::DemoteTo(df, tp), fsel, df, h->t + i);
    hn::BlendedStore(hn::DemoteTo(df, nx), fsel, df, h->nx + i);
    hn::BlendedStore(hn::DemoteTo(df, ny), fsel, df, h->ny + i);
    hn::BlendedStore(hn::DemoteTo(df, nz), fsel, df, h->nz + i);
    hn::BlendedStore(hn::Zero(df), fsel, df, h->u + i);
    hn::BlendedStore(hn::Zero(df), fsel, df, h->v + i);
    const auto k32 = hn::IfThenElseZero(hn::RebindMask(di32, sel32), hn::LoadU(di32, plane + i));
    const auto k2 = hn::Add(k32, k32);  // 2 indices a plane
    hn::BlendedStore(hn::GatherIndex(du32, planes.ids, k2), sel32, du32, h->material + i);
    hn::BlendedStore(hn::GatherIndex(du32, planes.ids, hn::Add(k2, hn::Set(di32, 1))), sel32, du32, h->object + i);
    hn::BlendedStore(hn::Zero(du32), sel32, du32, h->primitive + i);
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

void batch_nearest_planes(const RayBatch& rays, size_t n, const PlaneTable& planes, double* tp, int32_t* plane,
                          float* tfar) {
  HWY_DYNAMIC_DISPATCH(BatchNearestPlanes)(rays, n, planes, tp, plane, tfar);
}

void batch_triangle_hits(const uint32_t* select, uint32_t which, const uint32_t* prim, size_t n,
                         const TriangleTable& triangles, HitBatch* hits) {
  HWY_DYNAMIC_DISPATCH(BatchTriangleHits)(select, which, prim, n, triangles, hits);
}

void batch_plane_hits(const RayBatch& rays, const uint32_t* select, uint32_t which, const double* tp,
                      const int32_t* plane, size_t n, const PlaneTable& planes, HitBatch* hits) {
  HWY_DYNAMIC_DISPATCH(BatchPlaneHits)(rays, select, which, tp, plane, n, planes, hits);
}

}  // namespace tessera
#endif  // HWY_ONCE

// SPDX-License-Identifier: Apache-2.0
// world_batch.h's functions for each SIMD target, compiled by Google Highway and picked at run
// time (as render/triangle_cluster_simd.cpp). Each expression repeats the scalar code it names,
// operation for operation: the answers are bit for bit the scalar ones (ray_tracer_test.cpp
// checks every target).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "rays/world_batch_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <cmath>
#include <limits>

#include "rays/world_batch.h"

HWY_BEFORE_NAMESPACE();
namespace tessera::rays {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void WorldToRender(const WorldRay* rays, size_t n, const Vec3d& origin, double far, RayBatch* out, double* shift) {
  const hn::ScalableTag<double> dd;
  const hn::Rebind<float, decltype(dd)> df;
  const size_t N = hn::Lanes(dd);
  const auto one = hn::Set(dd, 1.0);
  // The rays' components copied into arrays first, by plain loads: gathering them straight from
  // the rays (56 bytes apart) was several times slower (perf: the gathers waited on each ray's
  // first touch, which sequential loads leave to the hardware prefetcher). Lanes past n repeat
  // the last ray.
  alignas(64) double c[6][kRayBatch];
  alignas(64) float t0[kRayBatch], t1[kRayBatch];
  const size_t padded = (n + N - 1) / N * N;
  for (size_t i = 0; i < padded; ++i) {
    const WorldRay& w = rays[i < n ? i : n - 1];
    c[0][i] = w.o.x, c[1][i] = w.o.y, c[2][i] = w.o.z;
    c[3][i] = w.d.x, c[4][i] = w.d.y, c[5][i] = w.d.z;
    t0[i] = w.tmin, t1[i] = w.tmax;
  }
  for (size_t i = 0; i < n; i += N) {
    const auto ox = hn::Load(dd, c[0] + i), oy = hn::Load(dd, c[1] + i), oz = hn::Load(dd, c[2] + i);
    const auto dx = hn::Load(dd, c[3] + i), dy = hn::Load(dd, c[4] + i), dz = hn::Load(dd, c[5] + i);
    const auto tmin = hn::PromoteTo(dd, hn::LoadU(df, t0 + i));
    const auto tmax_f = hn::LoadU(df, t1 + i);
    // unit_direction(): d itself where |d| is 1 to within 2^-20, else (d / max|d_k|) normalized.
    const auto len = hn::Sqrt(hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz)));
    const auto keep = hn::Le(hn::Abs(hn::Sub(len, one)), hn::Set(dd, kUnitTolerance));
    auto ux = dx, uy = dy, uz = dz;
    if (!hn::AllTrue(dd, keep)) {  // the divisions only where some ray needs them
      const auto m = hn::Max(hn::Abs(dx), hn::Max(hn::Abs(dy), hn::Abs(dz)));
      const auto sx = hn::Div(dx, m), sy = hn::Div(dy, m), sz = hn::Div(dz, m);
      const auto sl = hn::Sqrt(hn::Add(hn::Add(hn::Mul(sx, sx), hn::Mul(sy, sy)), hn::Mul(sz, sz)));
      ux = hn::IfThenElse(keep, dx, hn::Div(sx, sl));
      uy = hn::IfThenElse(keep, dy, hn::Div(sy, sl));
      uz = hn::IfThenElse(keep, dz, hn::Div(sz, sl));
    }
    // (o - origin) + dd t_min.
    const auto x = hn::Add(hn::Sub(ox, hn::Set(dd, origin.x)), hn::Mul(ux, tmin));
    const auto y = hn::Add(hn::Sub(oy, hn::Set(dd, origin.y)), hn::Mul(uy, tmin));
    const auto z = hn::Add(hn::Sub(oz, hn::Set(dd, origin.z)), hn::Mul(uz, tmin));
    const auto tmax = hn::Min(hn::PromoteTo(dd, tmax_f), hn::Set(dd, double(std::numeric_limits<float>::max())));
    hn::StoreU(hn::DemoteTo(df, x), df, out->ox + i);
    hn::StoreU(hn::DemoteTo(df, y), df, out->oy + i);
    hn::StoreU(hn::DemoteTo(df, z), df, out->oz + i);
    hn::StoreU(hn::DemoteTo(df, ux), df, out->dx + i);
    hn::StoreU(hn::DemoteTo(df, uy), df, out->dy + i);
    hn::StoreU(hn::DemoteTo(df, uz), df, out->dz + i);
    hn::StoreU(hn::DemoteTo(df, hn::Sub(tmax, tmin)), df, out->tmax + i);
    hn::StoreU(tmin, dd, shift + i);
    const auto far_start = hn::Gt(hn::Max(hn::Abs(x), hn::Max(hn::Abs(y), hn::Abs(z))), hn::Set(dd, far));
    uint8_t bits[8] = {};
    hn::StoreMaskBits(dd, far_start, bits);
    for (size_t k = 0; k < N && i + k < kRayBatch; ++k) out->skip[i + k] = uint8_t(far > 0.0 && ((bits[0] >> k) & 1));
  }
}

void ToWorld(const HitBatch& h, const RayBatch& r, const double* shift, size_t n, const Vec3d& origin,
             WorldAnswers* out) {
  const hn::ScalableTag<double> dd;
  const hn::Rebind<float, decltype(dd)> df;
  const hn::Rebind<uint8_t, decltype(dd)> du8;
  const hn::Rebind<uint32_t, decltype(dd)> du32;
  const hn::Rebind<uint64_t, decltype(dd)> du64;
  const size_t N = hn::Lanes(dd);
  const auto zero_f = hn::Zero(df);
  const auto none = hn::Set(du32, kNoIndex);
  for (size_t i = 0; i < n; i += N) {
    const auto t = hn::LoadU(df, h.t + i);
    const auto px = hn::LoadU(df, h.px + i), py = hn::LoadU(df, h.py + i), pz = hn::LoadU(df, h.pz + i);
    // to_world() accepts a hit whose t and point are finite.
    const auto finite = hn::And(hn::And(hn::IsFinite(t), hn::IsFinite(px)), hn::And(hn::IsFinite(py), hn::IsFinite(pz)));
    const auto answered = hn::Eq(hn::PromoteTo(du32, hn::LoadU(du8, h.status + i)), hn::Set(du32, uint32_t(HitBatch::kAnswered)));
    const auto ok = hn::And(answered, hn::RebindMask(du32, finite));
    const auto ok_f = hn::RebindMask(df, ok);
    const auto ok_d = hn::RebindMask(dd, hn::Eq(hn::PromoteTo(du64, hn::VecFromMask(du32, ok)), hn::Set(du64, 0xFFFFFFFFull)));
    uint8_t bits[8] = {};
    hn::StoreMaskBits(du32, ok, bits);
    for (size_t k = 0; k < N; ++k) out->hit[i + k] = (bits[0] >> k) & 1;
    // t exact where nothing moved (shift 0), else shift + t in double.
    const auto s = hn::LoadU(dd, shift + i);
    const auto moved = hn::DemoteTo(df, hn::Add(s, hn::PromoteTo(dd, t)));
    const auto unmoved = hn::Eq(hn::DemoteTo(df, s), zero_f);  // s == 0 exactly (s is a float's value)
    hn::StoreU(hn::IfThenElse(ok_f, hn::IfThenElse(unmoved, t, moved), hn::Set(df, HUGE_VALF)), df, out->t + i);
    hn::StoreU(hn::IfThenElseZero(ok_d, hn::Add(hn::Set(dd, origin.x), hn::PromoteTo(dd, px))), dd, out->px + i);
    hn::StoreU(hn::IfThenElseZero(ok_d, hn::Add(hn::Set(dd, origin.y), hn::PromoteTo(dd, py))), dd, out->py + i);
    hn::StoreU(hn::IfThenElseZero(ok_d, hn::Add(hn::Set(dd, origin.z), hn::PromoteTo(dd, pz))), dd, out->pz + i);
    // The normal facing the ray: n where dot(d, n) < 0, else -n (its sign bits flipped).
    const auto nx = hn::LoadU(df, h.nx + i), ny = hn::LoadU(df, h.ny + i), nz = hn::LoadU(df, h.nz + i);
    const auto dot = hn::Add(hn::Add(hn::Mul(hn::LoadU(df, r.dx + i), nx), hn::Mul(hn::LoadU(df, r.dy + i), ny)),
                             hn::Mul(hn::LoadU(df, r.dz + i), nz));
    const auto front = hn::Lt(dot, zero_f);
    hn::StoreU(hn::IfThenElseZero(ok_f, nx), df, out->nx + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, ny), df, out->ny + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, nz), df, out->nz + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, hn::IfThenElse(front, nx, hn::Neg(nx))), df, out->nsx + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, hn::IfThenElse(front, ny, hn::Neg(ny))), df, out->nsy + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, hn::IfThenElse(front, nz, hn::Neg(nz))), df, out->nsz + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, hn::LoadU(df, h.u + i)), df, out->u + i);
    hn::StoreU(hn::IfThenElseZero(ok_f, hn::LoadU(df, h.v + i)), df, out->v + i);
    hn::StoreU(hn::IfThenElse(ok, hn::LoadU(du32, h.object + i), none), du32, out->object + i);
    hn::StoreU(hn::IfThenElse(ok, hn::LoadU(du32, h.primitive + i), none), du32, out->primitive + i);
    hn::StoreU(hn::IfThenElse(ok, hn::LoadU(du32, h.material + i), none), du32, out->material + i);
  }
}

void StoreHitColumns(const WorldAnswers& a, size_t n, const HitColumns& c, size_t offset) {
  const hn::ScalableTag<double> dd;
  const hn::ScalableTag<float> df;  // twice dd's lanes
  const hn::ScalableTag<uint32_t> du32;
  const size_t Nd = hn::Lanes(dd), Nf = hn::Lanes(df);
  // Whole vectors up to the last full one; the rest (fewer than a vector's rays) one by one,
  // so nothing is written past index offset + n - 1.
  const size_t nd = n / Nd * Nd, nf = n / Nf * Nf;
  if (c.hit) {
    for (size_t i = 0; i < n; ++i) c.hit[offset + i] = char(a.hit[i]);
  }
  if (c.t) {
    for (size_t i = 0; i < nf; i += Nf) hn::StoreU(hn::LoadU(df, a.t + i), df, c.t + offset + i);
    for (size_t i = nf; i < n; ++i) c.t[offset + i] = a.t[i];
  }
  if (c.p) {
    double* p = c.p + 3 * offset;
    for (size_t i = 0; i < nd; i += Nd) {
      hn::StoreInterleaved3(hn::LoadU(dd, a.px + i), hn::LoadU(dd, a.py + i), hn::LoadU(dd, a.pz + i), dd, p + 3 * i);
    }
    for (size_t i = nd; i < n; ++i) p[3 * i] = a.px[i], p[3 * i + 1] = a.py[i], p[3 * i + 2] = a.pz[i];
  }
  auto three = [&](float* dst, const float* x, const float* y, const float* z) {
    dst += 3 * offset;
    for (size_t i = 0; i < nf; i += Nf) {
      hn::StoreInterleaved3(hn::LoadU(df, x + i), hn::LoadU(df, y + i), hn::LoadU(df, z + i), df, dst + 3 * i);
    }
    for (size_t i = nf; i < n; ++i) dst[3 * i] = x[i], dst[3 * i + 1] = y[i], dst[3 * i + 2] = z[i];
  };
  if (c.n) three(c.n, a.nx, a.ny, a.nz);
  if (c.ns) three(c.ns, a.nsx, a.nsy, a.nsz);
  if (c.uv) {
    float* uv = c.uv + 2 * offset;
    for (size_t i = 0; i < nf; i += Nf) hn::StoreInterleaved2(hn::LoadU(df, a.u + i), hn::LoadU(df, a.v + i), df, uv + 2 * i);
    for (size_t i = nf; i < n; ++i) uv[2 * i] = a.u[i], uv[2 * i + 1] = a.v[i];
  }
  auto copy = [&](uint32_t* dst, const uint32_t* src) {
    for (size_t i = 0; i < nf; i += Nf) hn::StoreU(hn::LoadU(du32, src + i), du32, dst + offset + i);
    for (size_t i = nf; i < n; ++i) dst[offset + i] = src[i];
  };
  if (c.object) copy(c.object, a.object);
  if (c.primitive) copy(c.primitive, a.primitive);
  if (c.material) copy(c.material, a.material);
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera::rays
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera::rays {

HWY_EXPORT(WorldToRender);
HWY_EXPORT(ToWorld);
HWY_EXPORT(StoreHitColumns);

void world_to_render(const WorldRay* rays, size_t n, const Vec3d& origin, double far, RayBatch* out, double* shift) {
  HWY_DYNAMIC_DISPATCH(WorldToRender)(rays, n, origin, far, out, shift);
}

void to_world(const HitBatch& hits, const RayBatch& rays, const double* shift, size_t n, const Vec3d& origin,
              WorldAnswers* out) {
  HWY_DYNAMIC_DISPATCH(ToWorld)(hits, rays, shift, n, origin, out);
}

void store_hit_columns(const WorldAnswers& answers, size_t n, const HitColumns& out, size_t offset) {
  HWY_DYNAMIC_DISPATCH(StoreHitColumns)(answers, n, out, offset);
}

}  // namespace tessera::rays
#endif  // HWY_ONCE

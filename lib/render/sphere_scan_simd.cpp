// SPDX-License-Identifier: Apache-2.0
// render/sphere_scan.h for each SIMD target (SSE4, AVX2, AVX-512), compiled by Google Highway and
// picked at run time, as render/sphere_roots_simd.cpp is.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/sphere_scan_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "render/ray_batch.h"
#include "render/sphere_scan.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// Why the margin is safe. With f = c - o (c the centre rounded to float) and a ray's line
// o + t d, the line passes within r of the centre when |f x d|^2 <= r^2 |d|^2, and the sphere lies
// wholly behind the origin when f . d < -r |d|. Each float operation errs by at most 2^-24 of its
// result; the centre's rounding adds 2^-24 |c|, and the components of f x d and f . d err by a
// few 2^-24 |f| |d|. With |f|_1 <= |c|_1 + |o|_1, a reach of r + 1e-5 (2 |c|_1 + r + the
// origins' bound) covers all of it more than tenfold (add_scan_sphere), so a lane left out
// provably has no root at t > 0. A NaN or an overflow compares false and keeps the lane: the
// exact test decides.
void ScanCandidates(const RayArrays& r, const ScanTable& table, uint32_t lanes, uint32_t* near) {
  const hn::CappedTag<float, kScanLanes> df;
  const size_t N = hn::Lanes(df);
  for (size_t s = 0; s < table.count; ++s) {
    const auto cx = hn::Set(df, table.cx[s]), cy = hn::Set(df, table.cy[s]), cz = hn::Set(df, table.cz[s]);
    const auto reach = hn::Set(df, table.reach[s]);
    uint32_t bits = 0;
    for (size_t j = 0; j < kScanLanes; j += N) {
      const auto dx = hn::LoadU(df, r.dx + j), dy = hn::LoadU(df, r.dy + j), dz = hn::LoadU(df, r.dz + j);
      const auto fx = hn::Sub(cx, hn::LoadU(df, r.ox + j));
      const auto fy = hn::Sub(cy, hn::LoadU(df, r.oy + j));
      const auto fz = hn::Sub(cz, hn::LoadU(df, r.oz + j));
      const auto ex = hn::Sub(hn::Mul(fy, dz), hn::Mul(fz, dy));
      const auto ey = hn::Sub(hn::Mul(fz, dx), hn::Mul(fx, dz));
      const auto ez = hn::Sub(hn::Mul(fx, dy), hn::Mul(fy, dx));
      const auto cross2 = hn::Add(hn::Add(hn::Mul(ex, ex), hn::Mul(ey, ey)), hn::Mul(ez, ez));
      const auto dd = hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz));
      const auto b = hn::Add(hn::Add(hn::Mul(fx, dx), hn::Mul(fy, dy)), hn::Mul(fz, dz));
      const auto lim = hn::Mul(hn::Mul(reach, reach), dd);
      const auto far_line = hn::Gt(cross2, lim);
      const auto behind = hn::And(hn::Lt(b, hn::Zero(df)), hn::Gt(hn::Mul(b, b), lim));
      uint8_t m[8] = {};
      hn::StoreMaskBits(df, hn::Not(hn::Or(far_line, behind)), m);
      bits |= uint32_t(m[0]) << j;
    }
    near[s] = bits & lanes;
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include <cmath>

namespace tessera {

HWY_EXPORT(ScanCandidates);

void add_scan_sphere(ScanTable* table, double cx, double cy, double cz, double radius, double origins) {
  const size_t s = table->count++;
  table->cx[s] = float(cx);
  table->cy[s] = float(cy);
  table->cz[s] = float(cz);
  // ScanCandidates' margin (why there): the radius, widened by 1e-5 of 2 |c|_1 + r + the
  // origins' bound, and by a floor that keeps its square a normal float.
  const double c1 = std::abs(cx) + std::abs(cy) + std::abs(cz);
  table->reach[s] = float(radius + 1e-5 * (2.0 * c1 + radius + origins) + 1e-18);
}

void scan_candidates(const RayArrays& rays, const ScanTable& table, uint32_t lanes, uint32_t* near) {
  HWY_DYNAMIC_DISPATCH(ScanCandidates)(rays, table, lanes, near);
}

}  // namespace tessera
#endif  // HWY_ONCE

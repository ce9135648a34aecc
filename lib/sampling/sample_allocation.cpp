// SPDX-License-Identifier: Apache-2.0
#include "sampling/sample_allocation.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tessera {

namespace {

// Counts are rounded up to whole pairs: each of a pixel's two sample streams (sampler.h) then
// takes the same number, so the stream difference behind the error estimate is balanced. They
// were whole packets of 8 while a packet held one pixel's samples; since packets fill across the
// pixels of a block (render/pixel_samples.h), a finer step wastes no lanes and lets a block stop
// closer to what the frame needs (docs/performance.md, "Target-error renders against uniform spp").
constexpr uint32_t kCountStep = 2;
uint32_t whole_steps(double n) { return uint32_t(std::ceil(n / double(kCountStep))) * kCountStep; }

}  // namespace

double predicted_frame_mse(const std::vector<BlockStat>& blocks, const std::vector<uint32_t>& counts) {
  double sum = 0, pixels = 0;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const BlockStat& s = blocks[b];
    pixels += double(s.pixels);
    if (s.mse > 0 && s.spp > 0) sum += double(s.pixels) * s.mse * std::pow(double(s.spp) / double(counts[b]), s.rate);
  }
  return pixels > 0 ? sum / pixels : 0.0;
}

std::vector<uint32_t> allocate_samples(const std::vector<BlockStat>& blocks, const AllocationBounds& bounds) {
  const size_t n = blocks.size();
  std::vector<uint32_t> lo(n), hi(n);
  for (size_t b = 0; b < n; ++b) {
    lo[b] = std::min(bounds.max_spp, std::max(blocks[b].spp, bounds.min_spp));
    hi[b] = std::max(lo[b], bounds.max_spp);
  }
  if (predicted_frame_mse(blocks, lo) <= bounds.frame_mse) return lo;
  if (predicted_frame_mse(blocks, hi) > bounds.frame_mse) return hi;

  // log n_b(mu) = (log mu + k_b) / (a_b + 1), k_b = log(a_b m_b n_b^a_b / c_b); bisect log mu between
  // the value that leaves every block at its lower bound and the one that sends every block to
  // its upper bound (the predicted MSE falls monotonically in mu). Everything but the one exp per
  // block and step is computed once: a frame of 2x2 blocks has hundreds of thousands of them,
  // and the plan is made between passes while no render thread works (it was 15% of a loose
  // target's CPU time with pow() in the loop and a fixed 64 steps).
  struct Term {
    double k = 0, inv_a1 = 0, log_lo = 0, log_hi = 0, log_spp = 0, rate = 0, weighted_mse = 0;
    double mse_lo = 0, mse_hi = 0;  // its term at its lower and upper bound
  };
  std::vector<Term> t(n);
  double lmu_lo = std::numeric_limits<double>::infinity(), lmu_hi = -lmu_lo, pixels = 0;
  for (size_t b = 0; b < n; ++b) {
    const BlockStat& s = blocks[b];
    pixels += double(s.pixels);
    Term& x = t[b];
    x.log_lo = std::log(double(lo[b]));
    x.log_hi = std::log(double(hi[b]));
    x.rate = s.rate;
    x.log_spp = s.spp > 0 ? std::log(double(s.spp)) : 0.0;
    x.weighted_mse = s.mse > 0 && s.spp > 0 ? double(s.pixels) * s.mse : 0.0;
    x.mse_lo = x.weighted_mse * std::exp(x.rate * (x.log_spp - x.log_lo));
    x.mse_hi = x.weighted_mse * std::exp(x.rate * (x.log_spp - x.log_hi));
    if (!(s.shape_mse > 0) || s.spp == 0) {
      x.k = -std::numeric_limits<double>::infinity();
      continue;
    }
    x.k = std::log(s.rate * s.shape_mse / std::max(s.cost, 1e-9)) + s.rate * x.log_spp;
    x.inv_a1 = 1.0 / (s.rate + 1);
    lmu_lo = std::min(lmu_lo, (s.rate + 1) * x.log_lo - x.k);
    lmu_hi = std::max(lmu_hi, (s.rate + 1) * x.log_hi - x.k);
  }
  auto log_count = [&](const Term& x, double lmu) {
    return std::isfinite(x.k) ? std::clamp((lmu + x.k) * x.inv_a1, x.log_lo, x.log_hi) : x.log_lo;
  };
  auto mse_at = [&](double lmu) {
    double sum = 0;
    for (const Term& x : t) {
      const double u = std::isfinite(x.k) ? (lmu + x.k) * x.inv_a1 : x.log_lo;
      sum += u <= x.log_lo ? x.mse_lo : u >= x.log_hi ? x.mse_hi : x.weighted_mse * std::exp(x.rate * (x.log_spp - u));
    }
    return sum / pixels;
  };
  // A step of 1e-7 in log mu moves a count by less than 1e-7 of itself, far below the rounding
  // to whole pairs; the bracket spans a few tens, so about 30 steps.
  for (int i = 0; i < 64 && lmu_hi - lmu_lo > 1e-7; ++i) {
    const double mid = 0.5 * (lmu_lo + lmu_hi);
    if (mse_at(mid) > bounds.frame_mse) lmu_lo = mid; else lmu_hi = mid;
  }
  std::vector<double> cont(n);
  for (size_t b = 0; b < n; ++b) cont[b] = std::exp(log_count(t[b], lmu_hi));
  std::vector<uint32_t> out(n);
  for (size_t b = 0; b < n; ++b) out[b] = std::clamp(whole_steps(cont[b] - 1e-9), lo[b], hi[b]);
  return out;
}

}  // namespace tessera

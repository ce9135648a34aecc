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
// closer to what the frame needs (docs/performance.md).
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
  // its upper bound (the predicted MSE falls monotonically in mu).
  std::vector<double> k(n, -std::numeric_limits<double>::infinity());
  double lmu_lo = std::numeric_limits<double>::infinity(), lmu_hi = -lmu_lo;
  for (size_t b = 0; b < n; ++b) {
    const BlockStat& s = blocks[b];
    if (!(s.shape_mse > 0) || s.spp == 0) continue;
    k[b] = std::log(s.rate * s.shape_mse / std::max(s.cost, 1e-9)) + s.rate * std::log(double(s.spp));
    lmu_lo = std::min(lmu_lo, (s.rate + 1) * std::log(double(lo[b])) - k[b]);
    lmu_hi = std::max(lmu_hi, (s.rate + 1) * std::log(double(hi[b])) - k[b]);
  }
  std::vector<double> cont(n);
  auto counts_at = [&](double lmu, std::vector<double>* out) {
    double sum = 0, pixels = 0;
    for (size_t b = 0; b < n; ++b) {
      const BlockStat& s = blocks[b];
      pixels += double(s.pixels);
      double c = double(lo[b]);
      if (std::isfinite(k[b])) c = std::clamp(std::exp((lmu + k[b]) / (s.rate + 1)), double(lo[b]), double(hi[b]));
      (*out)[b] = c;
      if (s.mse > 0 && s.spp > 0) sum += double(s.pixels) * s.mse * std::pow(double(s.spp) / c, s.rate);
    }
    return sum / pixels;
  };
  for (int i = 0; i < 64; ++i) {
    const double mid = 0.5 * (lmu_lo + lmu_hi);
    if (counts_at(mid, &cont) > bounds.frame_mse) lmu_lo = mid; else lmu_hi = mid;
  }
  counts_at(lmu_hi, &cont);
  std::vector<uint32_t> out(n);
  for (size_t b = 0; b < n; ++b) out[b] = std::clamp(whole_steps(cont[b] - 1e-9), lo[b], hi[b]);
  return out;
}

}  // namespace tessera

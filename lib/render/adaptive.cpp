// SPDX-License-Identifier: Apache-2.0
#include "render/adaptive.h"

#include <algorithm>
#include <cmath>

namespace tessera {

uint32_t next_sample_count(uint32_t n, double block_mse, double target_mse, uint32_t max_spp, uint32_t prev_n,
                           double prev_mse) {
  double a = 1.0;
  if (prev_n > 0 && prev_n < n && prev_mse > 0 && block_mse > 0) {
    a = std::clamp(std::log(prev_mse / block_mse) / std::log(double(n) / double(prev_n)), 1.0, 2.5);
  }
  const double want = std::ceil(double(n) * std::pow(block_mse / target_mse, 1.0 / a));
  uint64_t next = uint64_t(std::clamp(want, double(n) + 8.0, 2.0 * double(n)));
  next = (next + 7) / 8 * 8;
  return uint32_t(std::min<uint64_t>(next, max_spp));
}

SampleSummary summarize_samples(const std::vector<float>& variance, const std::vector<uint32_t>& spp, int width,
                                int height, const ImageSettings& settings) {
  SampleSummary s;
  const size_t pixels = size_t(width) * size_t(height);
  if (pixels == 0 || variance.size() != pixels || spp.size() != pixels) return s;
  s.pixels = int64_t(pixels);
  double var_sum = 0, spp_sum = 0;
  s.min_spp = spp[0];
  for (size_t i = 0; i < pixels; ++i) {
    var_sum += double(variance[i]);
    spp_sum += double(spp[i]);
    s.min_spp = std::min(s.min_spp, spp[i]);
    s.max_spp = std::max(s.max_spp, spp[i]);
  }
  s.estimated_rmse = std::sqrt(var_sum / double(pixels));
  s.mean_spp = spp_sum / double(pixels);
  if (!settings.adaptive()) return s;
  if (settings.frame_target()) {
    // The renderer's own test (frame_target.cpp) up to the order of summation.
    s.target_reached = s.estimated_rmse <= settings.target_rmse * (1 + 1e-9);
    if (!s.target_reached) {
      for (uint32_t n : spp) s.unconverged_pixels += n >= uint32_t(settings.max_spp) ? 1 : 0;
    }
    return s;
  }
  const double target_mse = settings.block_rmse * settings.block_rmse;
  for (int by = 0; by < height; by += kAdaptiveBlock) {
    for (int bx = 0; bx < width; bx += kAdaptiveBlock) {
      const int w = std::min(kAdaptiveBlock, width - bx), h = std::min(kAdaptiveBlock, height - by);
      double sum = 0;
      for (int y = by; y < by + h; ++y) {
        for (int x = bx; x < bx + w; ++x) sum += double(variance[size_t(y) * size_t(width) + size_t(x)]);
      }
      ++s.blocks;
      // The renderer's own test (tile_renderer.cpp), on the same float variances it stored.
      if (sum / double(w * h) > target_mse) {
        ++s.unconverged_blocks;
        s.unconverged_pixels += w * h;
        s.target_reached = false;
      }
    }
  }
  return s;
}

}  // namespace tessera

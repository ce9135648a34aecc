// SPDX-License-Identifier: Apache-2.0
// A pixel's running estimate: the sums of its two independent sample streams (sampler.h), from
// which come its value and an honest estimate of that value's variance.
#pragma once

#include <algorithm>
#include <cstdint>

#include "math/vec3.h"
#include "render/sampler.h"

namespace tessera {

class PixelEstimate {
 public:
  // Adds sample `sample`'s radiance. Samples must come in index order: the sums are then the same
  // sequence of double additions wherever and however often the pixel is rendered, and a pixel
  // that stopped at n samples is bit-identical to a uniform n-spp render of it.
  void add(uint32_t sample, const Rgb& L) {
    const uint32_t k = sample_stream(sample);
    for (int c = 0; c < 3; ++c) {
      sum_[k][c] += double(L[c]);
      sum_sq_[c] += double(L[c]) * double(L[c]);
    }
    ++n_[k];
  }

  uint32_t samples() const { return n_[0] + n_[1]; }

  // The pixel's value: the mean of all its samples.
  float mean(int c) const {
    const uint32_t n = samples();
    return n == 0 ? 0.0f : float((sum_[0][c] + sum_[1][c]) / double(n));
  }

  // Estimated variance of mean(), averaged over R, G, B; 0 below two samples (no estimate).
  //  - Stratified samplers (sobol, cmj): with A and B the two streams' means over n0 and n1
  //    samples, independent and unbiased, the value is (n0 A + n1 B) / n and
  //      E[(A - B)^2] n0 n1 / n^2 = Var(value)
  //    exactly when each stream's variance falls as 1/count, and to within the streams' size
  //    difference of one sample for stratified ones. Unlike the sample variance it needs no
  //    assumption about how the samples within a stream are correlated, which is what made the
  //    sample variance 2-13x too high for stratified samples. It has one degree of freedom per
  //    channel: noisy per pixel, unbiased on average (docs/renderer.md, "Error estimate").
  //  - Independent samples (independent, center): the sample variance / n, unbiased too and with
  //    n - 1 degrees of freedom, so it is the better estimate where it is valid.
  double variance(SamplerKind kind) const {
    if (n_[1] == 0) return 0.0;
    if (kind == SamplerKind::kIndependent || kind == SamplerKind::kCenter) return sample_variance();
    const double n = double(samples());
    const double w = double(n_[0]) * double(n_[1]) / (n * n);
    double v = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = sum_[0][c] / double(n_[0]) - sum_[1][c] / double(n_[1]);
      v += d * d * w;
    }
    return v / 3.0;
  }

  // The stopping rule's floor for a stratified pixel (render/adaptive.h): its sample variance
  // s^2 falling as spp^-1.5, the rate of a (0,2)-net on a pixel crossed by an edge. The
  // two-stream estimate is unbiased but, for an edge pixel, often exactly 0: stratification makes
  // both streams count the same number of samples on each side of the edge, so they agree until
  // the count of one of them moves by one. Over a frame that averages out; over a block with a
  // few bright edge pixels it stopped the block at min_spp with most of the frame's error
  // (measured on the Cornell box: one such block held 88% of it). The reported estimate stays the
  // unbiased one. A floor falling as spp^-2 was tried: slightly faster on Cornell at high
  // targets, but target-error renders then estimated their own error 0.75-0.90x of the measured
  // one, against 0.81-0.98x with this floor (measured with bench/speed_error).
  double stratified_floor() const {
    if (n_[1] == 0) return 0.0;
    const double n = double(samples());
    return sample_variance() / std::sqrt(n);
  }

 private:
  double sample_variance() const {
    const double n = double(samples());
    double v = 0;
    for (int c = 0; c < 3; ++c) {
      const double sum = sum_[0][c] + sum_[1][c];
      // One-pass formula: cancellation costs relative precision ~1e-16 * mean^2 / variance,
      // far below any error worth estimating; never negative.
      v += std::max(0.0, (sum_sq_[c] - sum * sum / n) / (n - 1.0)) / n;
    }
    return v / 3.0;
  }

  double sum_[2][3] = {};
  double sum_sq_[3] = {};
  uint32_t n_[2] = {};
};

}  // namespace tessera

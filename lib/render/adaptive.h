// SPDX-License-Identifier: Apache-2.0
// Rendering to a target error: the block rule that decides when pixels have enough samples, and
// the summary of how a frame's samples were spent.
//
// Decisions are made per block of kAdaptiveBlock x kAdaptiveBlock pixels aligned to the image
// (clipped at its right and bottom edges), at sample counts that depend only on the block's own
// samples: a pixel is then a pure function of (scene, frame, settings), whatever the tiling,
// thread count or worker. Why blocks and not single pixels: a pixel's own error estimate has one
// degree of freedom per channel, so a pixel whose true error is 3x the target has a one-in-four
// chance per check of estimating itself below it and stopping; a block's mean over 64 pixels is
// stable enough to stop on (docs/renderer.md, "Rendering to a target error", has the
// measurements).
#pragma once

#include <cstdint>
#include <vector>

#include "scene/scene.h"

namespace tessera {

constexpr int kAdaptiveBlock = 8;

// The sample count a block goes on to after a check at n samples found its mean estimated
// variance `block_mse` above `target_mse`: the count at which the estimate would meet the target
// if it kept falling as spp^-a, with a measured from the block's previous check (`prev_n`,
// `prev_mse`; 0 when there is none) and clamped to [1, 2.5] (a = 1, independent samples, when
// there is no previous check: stratified blocks fall faster, so this overshoots at most once);
// at least n + 8 and at most 2n (a noisy estimate cannot send a block far past what it needs), a
// multiple of 8 (whole packets), and at most max_spp.
uint32_t next_sample_count(uint32_t n, double block_mse, double target_mse, uint32_t max_spp, uint32_t prev_n = 0,
                           double prev_mse = 0);

// How a frame's samples were spent, from its per-pixel estimated variance and sample counts.
struct SampleSummary {
  double estimated_rmse = 0;  // sqrt(mean estimated variance): the frame's estimated RMSE
  uint32_t min_spp = 0, max_spp = 0;
  double mean_spp = 0;
  int64_t pixels = 0;
  // Block-bound renders (block_rmse): blocks whose estimated RMSE is still above the bound (they
  // stopped at max_spp), and the pixels they hold. Frame-target renders (target_rmse): the pixels
  // at max_spp when the frame's estimate is above the target, else 0.
  int64_t blocks = 0, unconverged_blocks = 0, unconverged_pixels = 0;
  bool target_reached = true;  // adaptive renders: the frame or every block met its target
};

SampleSummary summarize_samples(const std::vector<float>& variance, const std::vector<uint32_t>& spp, int width,
                                int height, const ImageSettings& settings);

}  // namespace tessera

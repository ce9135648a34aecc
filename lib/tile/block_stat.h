// SPDX-License-Identifier: Apache-2.0
// A block's statistics after its samples so far: what a frame-target render (render/
// frame_target.h) allocates the next pass's samples from. A value type of the tile module
// because tiles carry them: a worker reports the statistics of the blocks it rendered, and the
// coordinator gathers a frame's to plan its next pass.
#pragma once

#include <array>
#include <cstdint>

namespace tessera {

struct BlockStat {
  int64_t block = 0;    // row-major index in the frame's grid of blocks
  uint32_t spp = 0;     // samples each of its pixels has
  uint32_t pixels = 0;  // pixels in it (fewer at the image's right and bottom edges)
  double mse = 0;       // mean over its pixels of the estimated variance of the pixel's value
  // What the allocation shares samples by: mse, or a floor on it where mse is not trusted
  // (PixelEstimate::stratified_floor); at least mse.
  double shape_mse = 0;
  double cost = 0;      // rays traced per sample, averaged over its samples so far (> 0)
  double rate = 1;      // its MSE falls as spp^-rate (set by whoever plans: not carried by tiles)
  // The mean of its pixels' values (linear RGB): set against its neighbours' by the planner, it
  // shows an edge that the block's own samples could not (sampling/pass_plan.cpp).
  std::array<float, 3> mean{};
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Where a frame's samples go when the frame has a target error: the allocation that minimises the
// frame's cost for its predicted error, from per-block statistics of the samples taken so far.
//
// With block b's estimated error (the mean over its pixels of the variance of a pixel's value)
// m_b at n_b samples, falling as (n_b / n)^a_b, and its cost c_b per sample, the frame's MSE at
// counts n is sum_b p_b m_b (n_b / n)^a_b / P and its cost sum_b p_b c_b n; minimising the cost
// for MSE = E^2 (Lagrange) gives each block
//     n = (mu a_b m_b n_b^a_b / c_b)^(1 / (a_b + 1)),
// one multiplier mu for the whole frame. At a_b = 1 that is n proportional to sigma_b / sqrt(c_b),
// the per-sample deviation over the root of the cost per sample: expensive blocks (glass) end
// above the target and cheap ones below, which a rule asking every block to meet the target
// cannot do (docs/performance.md, "Target-error renders against uniform spp").
//
// Everything here is a pure function of its inputs, evaluated in block order: the same statistics
// give the same counts in `tessera render` and at a coordinator.
#pragma once

#include <cstdint>
#include <vector>

#include "tile/block_stat.h"

namespace tessera {

struct AllocationBounds {
  double frame_mse = 0;  // the target: the frame's mean pixel MSE
  uint32_t min_spp = 0, max_spp = 0;
};

// The frame's predicted MSE with block b at counts[b] samples.
double predicted_frame_mse(const std::vector<BlockStat>& blocks, const std::vector<uint32_t>& counts);

// Sample counts per block (each at least its spp and min_spp, at most max_spp, even: a pixel's
// two sample streams take the same number) of least cost whose predicted frame MSE is at most bounds.frame_mse; every block
// at max_spp when even that predicts more.
std::vector<uint32_t> allocate_samples(const std::vector<BlockStat>& blocks, const AllocationBounds& bounds);

}  // namespace tessera

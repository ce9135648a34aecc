// SPDX-License-Identifier: Apache-2.0
// A frame target's passes (ImageSettings::target_rmse, docs/renderer.md): the grid of
// allocation blocks, each block's record across passes, the decision between passes and each
// tile's share of it. Pure functions of the blocks' statistics, evaluated in block order: the
// renderer (render/frame_target.h) and the coordinator, which plans a farm's passes from the
// statistics its workers report, make the same decisions from the same numbers.
//
//   pass 1 (pilot)  every block to min_spp samples; its statistics: each block's error, cost and
//                   mean value
//   pass 2          each block to the count the allocation gives for the frame's target
//   pass 3 ...      only while the frame's estimate is still above the target: the allocation
//                   again, from the latest statistics and each block's measured rate of
//                   convergence (at most kMaxTargetPasses passes)
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sampling/sample_allocation.h"
#include "scene/scene.h"
#include "tile/block_stat.h"
#include "tile/tile_rect.h"

namespace tessera {

// The allocation's unit: blocks of 2x2 pixels. With the contrast floor (pass_plan.cpp) and a
// pilot of 2 samples, 2x2 blocks reach an error with 1.4x fewer rays than 4x4 blocks and a pilot
// of 4 (Whitted showcase, 640x360; docs/performance.md, "Target-error renders against uniform
// spp"); without the floor their estimate fell to 0.63-0.77x of the measured error.
constexpr int kAllocationBlock = 2;
constexpr int kMaxTargetPasses = 8;

// The grid of allocation blocks over a width x height image.
struct BlockGrid {
  int width = 0, height = 0, cols = 0, rows = 0;
  BlockGrid(int w, int h)
      : width(w), height(h), cols((w + kAllocationBlock - 1) / kAllocationBlock),
        rows((h + kAllocationBlock - 1) / kAllocationBlock) {}
  int count() const { return cols * rows; }
  // The blocks a tile renders (those it meets), as [col0, col1) x [row0, row1).
  struct Range {
    int col0 = 0, row0 = 0, col1 = 0, row1 = 0;
    int count() const { return (col1 - col0) * (row1 - row0); }
  };
  Range meeting(const TileRect& rect) const;
  // How many blocks have their first pixel in the tile (the blocks whose statistics it reports).
  int origins_in(const TileRect& rect) const;
};

// A tile's sample plan: the count of every block the tile meets, row-major over
// BlockGrid::meeting(rect). Empty: the pilot (every block at min_spp).
using SamplePlan = std::vector<uint32_t>;

// How a block's MSE is assumed to fall with spp before two passes have measured it.
double first_rate(SamplerKind sampler);

// A block's record after a new measurement: unchanged when the count did not move (a tile
// rendered again for its other blocks), else `now` with its rate measured from `before`.
BlockStat updated_stat(const BlockStat& before, const BlockStat& now);

// The decision between passes, from every block's latest statistics in block order after
// `passes_done` passes: the next pass's count per block, or nothing when the frame is done (its
// predicted estimate meets the target, no block can take more, or kMaxTargetPasses passes).
std::optional<std::vector<uint32_t>> next_pass_counts(const std::vector<BlockStat>& stats, const BlockGrid& grid,
                                                      const ImageSettings& img, int passes_done);

// Pixels whose values are final before the passes begin (the lattice sampler's smooth pixels,
// render/lattice_sampler.h).
struct FrozenPixels {
  // Per block: 1 where all its pixels are frozen; its statistics are then theirs and its count
  // never moves. Every other block's statistics cover only its pixels that are not frozen.
  std::vector<uint8_t> blocks;
  double error = 0;          // the sum over every frozen pixel of its estimated variance
  int64_t frame_pixels = 0;  // all the frame's pixels
};

// The decision between passes for a frame with frozen pixels: their error counts toward the
// target as it is, and the other pixels' blocks share what is left of it, but at least half of it
// a pixel: where the frozen pixels' error takes more than the rest of the target (sub-pixel
// features the lattice missed and its audits found), the target is out of reach, and pushing the
// other pixels far below it sent a quarter of a Whitted frame's pixels to max_spp for nothing.
std::optional<std::vector<uint32_t>> next_pass_counts(const std::vector<BlockStat>& stats, const BlockGrid& grid,
                                                      const ImageSettings& img, int passes_done,
                                                      const FrozenPixels& frozen);

// The plan of one tile for a pass, from the frame's counts.
SamplePlan tile_plan(const BlockGrid& grid, const TileRect& rect, const std::vector<uint32_t>& counts);

// Plans on the wire: little-endian uint32 counts.
std::string encode_plan(const SamplePlan& plan);
// Empty bytes: the pilot. "" when `*plan` is set, else what is wrong ("sample plan of 7 bytes is
// not a whole number of 4-byte counts").
std::string decode_plan(const std::string& bytes, SamplePlan* plan);

}  // namespace tessera

// Rendering a frame to a target error (ImageSettings::target_rmse, the frame's RMSE): passes over
// blocks of kAllocationBlock^2 pixels, each pass taking the samples the allocation of the
// previous pass's statistics asks for (render/sample_allocation.h).
//
//   pass 1 (pilot)  every block to min_spp samples; its statistics: each block's error and cost
//   pass 2          each block to the count the allocation gives for the frame's target
//   pass 3 ...      only while the frame's estimate is still above the target: the allocation
//                   again, from the latest statistics and each block's measured rate of
//                   convergence (at most kMaxTargetPasses passes)
//
// A pixel is a pure function of (scene, frame, settings): its samples are the first n of its
// sequence, n a pure function of every block's statistics, which are pure functions of their
// pixels' samples. The same pieces make the frame in-process (render_frame_to_target, which
// continues each pixel where the last pass stopped) and on a farm (render_tile_planned renders a
// tile's blocks from sample 0 to their planned counts; the coordinator gathers the blocks'
// statistics and calls next_pass_counts): the same bits for any thread count, tile size or farm.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "render/pixel_estimate.h"
#include "render/render_scene.h"
#include "render/sample_allocation.h"
#include "render/tile_renderer.h"

namespace tessera {

constexpr int kAllocationBlock = 4;
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
};

// A tile's sample plan: the count of every block the tile meets, row-major over
// BlockGrid::meeting(rect). Empty: the pilot (every block at min_spp).
using SamplePlan = std::vector<uint32_t>;

// Block statistics from its pixels' estimates (row-major within the block, w x h) after `spp`
// samples each and the rays they took. Its rate is the default for the sampler.
BlockStat block_stat(int64_t block, const PixelEstimate* pixels, int w, int h, uint32_t spp, uint64_t rays,
                     SamplerKind sampler);

// A block's record after a new measurement: unchanged when the count did not move (a tile
// rendered again for its other blocks), else `now` with its rate measured from `before`.
BlockStat updated_stat(const BlockStat& before, const BlockStat& now);

// The decision between passes, from every block's latest statistics in block order after
// `passes_done` passes: the next pass's count per block, or nothing when the frame is done (its
// predicted estimate meets the target, no block can take more, or kMaxTargetPasses passes).
std::optional<std::vector<uint32_t>> next_pass_counts(const std::vector<BlockStat>& stats, const BlockGrid& grid,
                                                      const ImageSettings& img, int passes_done);

// The plan of one tile for a pass, from the frame's counts.
SamplePlan tile_plan(const BlockGrid& grid, const TileRect& rect, const std::vector<uint32_t>& counts);

// Renders a tile of a frame-target render: every block the tile meets, from sample 0 to its
// planned count (throws std::invalid_argument for a plan of the wrong size or a count outside
// [min_spp, max_spp]); keeps the tile's own pixels and reports the statistics of the blocks whose
// first pixel lies in it.
TileResult render_tile_planned(const RenderScene& scene, const TileRect& rect, const SamplePlan& plan);

// Renders the frame to its target RMSE in-process with `threads` threads (0 = all cores).
// `progress` is called with (samples done, samples planned so far) after each block of a pass.
FrameResult render_frame_to_target(const RenderScene& scene, int threads,
                                   const std::function<void(int64_t, int64_t)>& progress = {});

}  // namespace tessera

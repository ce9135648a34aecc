// Rendering a frame to a target error (ImageSettings::target_rmse, the frame's RMSE): passes over
// blocks of kAllocationBlock^2 pixels, each pass taking the samples the allocation of the
// previous pass's statistics asks for (render/sample_allocation.h).
//
//   pass 1 (pilot)  every block to min_spp samples; its statistics: each block's error and cost
//   pass 2          each block to the count the allocation gives for the frame's target
//   pass 3 ...      only while the frame's estimate is still above the target: the allocation
//                   again, from the latest statistics and each block's measured rate of
//                   convergence (at most kMaxTargetPasses passes; a pass continues each pixel
//                   where the last one stopped, so passes cost nothing but their decisions)
//
// A pixel is a pure function of (scene, frame, settings): its samples are the first n of its
// sequence, n a pure function of every block's statistics, which are pure functions of their
// pixels' samples. The frame is the same for any thread count, tile size or farm.
#pragma once

#include <functional>
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
};

// Block `b`'s statistics from its pixels' estimates (row-major within the block) after `spp`
// samples each and the rays they took; `prev` (optional) is the block's statistics at an earlier
// pass, from which its rate of convergence is measured.
BlockStat block_stat(const PixelEstimate* pixels, int w, int h, uint32_t spp, uint64_t rays, SamplerKind sampler,
                     const BlockStat* prev);

// Renders the frame to its target RMSE in-process with `threads` threads (0 = all cores).
// `progress` is called with (samples done, samples planned so far) after each block of a pass.
FrameResult render_frame_to_target(const RenderScene& scene, int threads,
                                   const std::function<void(int64_t, int64_t)>& progress = {});

}  // namespace tessera

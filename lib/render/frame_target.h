// SPDX-License-Identifier: Apache-2.0
// Rendering a frame to a target error (ImageSettings::target_rmse, the frame's RMSE): passes over
// blocks of kAllocationBlock^2 pixels, each pass taking the samples the allocation of the
// previous pass's statistics asks for (sampling/sample_allocation.h).
//
// (sampling/pass_plan.h has the passes and their decisions.)
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
#include "sampling/pass_plan.h"
#include "render/tile_renderer.h"

namespace tessera {

// Block statistics from its pixels' estimates (row-major within the block, w x h) after `spp`
// samples each and the rays they took. Its rate is the default for the sampler.
BlockStat block_stat(int64_t block, const PixelEstimate* pixels, int w, int h, uint32_t spp, uint64_t rays,
                     SamplerKind sampler);

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

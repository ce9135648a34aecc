// SPDX-License-Identifier: Apache-2.0
// The tile API the worker calls, and the in-process frame render built on it.
#pragma once

#include <functional>

#include "image/image.h"
#include "render/adaptive.h"
#include "render/lattice_cost.h"
#include "render/render_scene.h"
#include "tile/tile_result.h"

namespace tessera {

// Renders one tile of the scene's frame. Thread-safe; each pixel is a pure function of
// (scene, frame, pixel), so results are bit-identical for any tiling, order or thread count.
TileResult render_tile(const RenderScene& scene, const TileRect& rect);

struct FrameResult {
  ImageRGB image;
  std::vector<float> variance;  // per pixel, as in TileResult
  std::vector<uint32_t> spp;    // per pixel, as in TileResult
  RayCounts rays;
  double seconds = 0;
  ImageSettings settings;       // what it was rendered with (the target error, if any)
  LatticeCost lattice;          // a --sampler lattice frame's rays and time by stage; zero otherwise
  // Estimated RMSE of the image against the converged one: sqrt(mean pixel variance).
  double estimated_rmse() const;
  // The estimate with the spp range and, for a target-error render, the blocks left above it.
  SampleSummary summary() const;
};

// Renders a whole frame in-process with `threads` threads (0 = all cores), tile by tile.
// `progress` (optional) is called after each tile with (tiles done, tiles total).
FrameResult render_frame(const RenderScene& scene, int tile_size = 32, int threads = 0,
                         const std::function<void(int, int)>& progress = {});

}  // namespace tessera

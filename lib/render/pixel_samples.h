// SPDX-License-Identifier: Apache-2.0
// A pixel's samples, rendered and stored: the one place where camera samples become radiance in
// a pixel's running estimate, shared by every way of choosing how many samples a pixel takes
// (uniform spp, the block bound, the frame target).
#pragma once

#include <cstddef>
#include <cstdint>

#include "render/pixel_estimate.h"
#include "render/render_scene_internal.h"
#include "tile/tile_rect.h"
#include "tile/tile_result.h"

namespace tessera {

// Renders samples [from, to) of every pixel of `pixels` into its estimate, est[(y - y0) * width +
// (x - x0)], counting the rays in `rays`. Samples go into packets in (pixel, sample) order, across
// pixels where one has fewer samples left than a packet's lanes: a lane's result depends only on
// its pixel and sample index (integrator.h), never on which samples share its packet, so a pixel
// rendered to n samples in any number of steps, in any rectangle, tile or thread, is
// bit-identical to one rendered to n in one step.
void render_samples(const RenderScene& scene, const TileRect& pixels, uint32_t from, uint32_t to, PixelEstimate* est,
                    RayCounts* rays);

// The same for a list of pixels, each with its own samples [from, to) (from < to) and estimate,
// rendered in list order and packed across pixels the same way: the lattice sampler's edge pixels,
// scattered over the frame (render/lattice_sampler.h).
struct PixelRun {
  int x = 0, y = 0;
  uint32_t from = 0, to = 0;
  PixelEstimate* est = nullptr;
};
void render_pixel_runs(const RenderScene& scene, const PixelRun* runs, size_t n, RayCounts* rays);

// Stores pixel `i` of `out` (its mean, its variance estimate at the precision tiles carry it, its
// sample count).
void store_pixel(const PixelEstimate& est, SamplerKind kind, size_t i, TileResult* out);

}  // namespace tessera

// A pixel's samples, rendered and stored: the one place where camera samples become radiance in
// a pixel's running estimate, shared by every way of choosing how many samples a pixel takes
// (uniform spp, the block bound, the frame target).
#pragma once

#include <cstddef>
#include <cstdint>

#include "render/pixel_estimate.h"
#include "render/render_scene.h"
#include "tile/tile_result.h"

namespace tessera {

// Renders samples [from, to) of pixel (x, y) into `est`, counting the rays in `rays`. Samples
// s0 .. s0+7 form one packet (s0 a multiple of 8): which rays share a packet depends on the pixel
// and sample index only, never on the tile, thread or stopping point, so a pixel rendered to n
// samples in any number of steps is bit-identical to one rendered to n in one step.
void render_samples(const RenderScene& scene, int x, int y, uint32_t from, uint32_t to, PixelEstimate* est,
                    RayCounts* rays);

// Stores pixel `i` of `out` (its mean, its variance estimate at the precision tiles carry it, its
// sample count).
void store_pixel(const PixelEstimate& est, SamplerKind kind, size_t i, TileResult* out);

}  // namespace tessera

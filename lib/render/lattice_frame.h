// SPDX-License-Identifier: Apache-2.0
// A frame target rendered with the lattice sampler (render/lattice_sampler.h): its pilot settles
// the smooth pixels, then passes take the edge pixels' samples (the default sampler's two
// streams) as render/frame_target.h's passes do, allocated per allocation block from the blocks'
// edge pixels alone, the smooth pixels' audited error counted toward the target as it is.
//
// Every pass renders each row of allocation blocks as one list of edge pixels, packed across the
// row's blocks (a block often has one edge pixel, a packet's worth of samples only together with
// its neighbours'); the row's rays are shared among its blocks in proportion to their samples for
// their cost. Rows are fixed, so every number is the same for any thread count.
#pragma once

#include <cstdint>
#include <functional>

#include "render/render_scene.h"
#include "render/tile_renderer.h"

namespace tessera {

// Renders the frame in-process with `threads` threads (0 = all cores); `progress` as
// render_frame_to_target's.
FrameResult render_frame_lattice(const RenderScene& scene, int threads,
                                 const std::function<void(int64_t, int64_t)>& progress = {});

}  // namespace tessera

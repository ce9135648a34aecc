// The Whitted integrator: direct lighting with hard shadows from point and directional lights
// (and one sample per area light), perfect mirrors, and dielectrics with exact Fresnel and total
// internal reflection, recursing up to max_depth.
#pragma once

#include "render/render_scene.h"
#include "render/sampler.h"
#include "render/tile.h"

namespace tessera {

// Radiance arriving at the eye along `ray` for one pixel sample.
Rgb trace_radiance(const RenderScene& scene, const Ray& ray, const PixelSampler& sampler, RayCounts* counts);

}  // namespace tessera

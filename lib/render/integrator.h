// SPDX-License-Identifier: Apache-2.0
// The Whitted integrator: direct lighting with hard shadows from point and directional lights
// (and one sample per area light), perfect mirrors, and dielectrics with exact Fresnel and total
// internal reflection, recursing up to max_depth.
#pragma once

#include "render/render_scene_internal.h"
#include "render/sampler.h"
#include "tile/tile_result.h"

namespace tessera {

struct RayLanes;

// Radiance arriving at the eye along `ray` for one pixel sample: a packet of one.
Rgb trace_radiance(const RenderScene& scene, const Ray& ray, const PixelSampler& sampler, RayCounts* counts);

// The same for n <= RenderScene::kPacket camera rays (lane i with samplers[i]), traced as one
// packet; their shadow rays go in packets, light after light, and their reflection and
// refraction rays in one packet per node of the path tree, all the way down. The work around
// Embree's queries runs over the lanes in SIMD where it pays (docs/renderer.md, "Across SIMD
// widths"). Lane i's result is bit-identical to trace_radiance(rays[i], samplers[i]): it does
// not depend on the other lanes. Pack rays as a pure function of the pixel (see
// RenderScene::intersect_packet).
void trace_radiance_packet(const RenderScene& scene, const Ray* rays, const PixelSampler* samplers, int n,
                           RayCounts* counts, Rgb* out);
// The same with the rays as arrays of components (render/ray_lanes.h), as the tile renderer
// makes camera rays: the form every stage reads them in.
void trace_radiance_packet(const RenderScene& scene, const RayLanes& rays, const PixelSampler* samplers, int n,
                           RayCounts* counts, Rgb* out);

}  // namespace tessera

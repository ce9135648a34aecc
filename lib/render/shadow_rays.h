// SPDX-License-Identifier: Apache-2.0
// The shadow rays of a packet's diffuse hits toward one point, spot or directional light, set up
// for all lanes at once (structure of arrays, Google Highway at the machine's width, picked at
// run time): per lane, the direction and distance to the light, the cosine weight (flat, or the
// shading normal's with the terminator term of shading_normal.h), a spot's cone falloff and the
// robust spawn of render/ray.h's offset_ray_origin. Only IEEE add, subtract, multiply, divide and
// square root, never fused (the project builds with -ffp-contract=off), in the order of the
// scalar functions named, so a lane's bits do not depend on the vector width (integrator_test.cpp
// compares frames across every target this machine runs; tile_renderer_test.cpp and
// gltf_render_test.cpp check the light against analytic values).
//
// Why: per lane this set-up is two square roots, four divisions and a robust spawn per light, and
// done one lane at a time it was the largest single item of a Whitted frame's profile after the
// packet bookkeeping (docs/performance.md, "Packets and SIMD stages").
#pragma once

#include <cstdint>

#include "math/vec3.h"
#include "render/ray_lanes.h"
#include "render/spawn_lanes.h"

namespace tessera {

inline constexpr int kShadowLanes = kSpawnLanes;
static_assert(kShadowLanes == kRayLanes);

// Where shadow rays start: a packet's diffuse hits, as arrays of components.
struct ShadingPoints {
  SpawnLanes at;  // where the shadow rays leave from (the normal faces the viewer)
  // Smooth lanes: the shading normal on the viewer's side (shading_normal.h, facing()) and its
  // cosine with the geometric one; flat lanes: ignored.
  alignas(32) float sx[kShadowLanes], sy[kShadowLanes], sz[kShadowLanes];
  alignas(32) float g_dot_s[kShadowLanes];
  alignas(32) int32_t smooth[kShadowLanes];  // 1: weigh light by the shading normal
  alignas(32) int32_t live[kShadowLanes];    // 1: a diffuse hit; 0: no shadow rays
};

// One light's shadow rays from the live lanes of a ShadingPoints. A lane's ray is live where the
// light is above its surface (and, for a spot, inside the cone); its direct light is then
// transmittance x intensity (x cone, for spots) x b.
struct ShadowRays {
  // The rays as a packet takes them: a light's rays from a full packet of diffuse hits go to
  // Embree from here, with no copy (integrator.cpp).
  RayLanes rays;
  alignas(32) float cone[kShadowLanes];  // spot lights: the cone's falloff; else 1
  alignas(32) float b[kShadowLanes];     // point, spot: cos(theta) / r^2; directional: cos(theta)
  alignas(32) int32_t live[kShadowLanes];
};

// A spot's cone (RenderScene::SpotLight::falloff): its axis and the falloff's scale and offset.
struct SpotCone {
  Vec3f direction;
  float scale, offset;
};

// Rays to a point light at `position`, or a spot light when `spot` is given.
void point_light_rays(const ShadingPoints& points, const Vec3f& position, const SpotCone* spot, ShadowRays* out);
// Rays toward a directional light: `w` is the unit direction to the light (minus the way it travels).
void directional_light_rays(const ShadingPoints& points, const Vec3f& w, ShadowRays* out);

}  // namespace tessera

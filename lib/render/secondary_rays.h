// SPDX-License-Identifier: Apache-2.0
// The reflection and refraction rays of a packet's flat mirror and glass hits, set up for all
// lanes at once (structure of arrays, Google Highway at the machine's width, picked at run time):
// per lane the mirror direction about the facing normal, for glass the exact Fresnel reflectance
// and the refracted direction (render/fresnel.h), and the robust spawn of render/ray.h's
// offset_ray_origin toward each. The arithmetic is integrator.cpp's plan_secondary for a flat
// hit, operation for operation and in the same order, with IEEE add, subtract, multiply, divide
// and square root only (never fused), so a lane's bits do not depend on the vector width
// (integrator_test.cpp compares every target this machine runs against a packet of one).
//
// Why: per lane a glass hit costs two square roots and six divisions before its rays exist, and
// done one lane at a time their latencies were the largest item of radiance_packet's own time on
// the Whitted showcase (perf annotate; docs/performance.md, "Packets and SIMD stages"). Smooth
// (shading-normal) hits keep the scalar path: their turning normal and side checks
// (shading_normal.h) branch per lane.
#pragma once

#include <cstdint>

#include "render/spawn_lanes.h"

namespace tessera {

inline constexpr int kTurnLanes = kSpawnLanes;

// A packet's flat mirror and glass hits, as arrays of components.
struct TurningPoints {
  SpawnLanes at;  // where the rays leave from
  alignas(32) float dx[kTurnLanes], dy[kTurnLanes], dz[kTurnLanes];  // the arriving ray's direction
  alignas(32) float eta_i[kTurnLanes], eta_t[kTurnLanes];            // glass: indices, from and into
  alignas(32) int32_t glass[kTurnLanes];                             // 1: glass; 0: mirror
  alignas(32) int32_t live[kTurnLanes];                              // 1: set this lane up
};

// What the live lanes send on: a reflection ray (mirrors always; glass where R > 0) and a
// refraction ray (glass where R < 1), and glass's Fresnel reflectance R.
struct SecondaryRays {
  alignas(32) float rox[kTurnLanes], roy[kTurnLanes], roz[kTurnLanes];  // reflection: origin
  alignas(32) float rdx[kTurnLanes], rdy[kTurnLanes], rdz[kTurnLanes];  // and direction
  alignas(32) float tox[kTurnLanes], toy[kTurnLanes], toz[kTurnLanes];  // refraction: origin
  alignas(32) float tdx[kTurnLanes], tdy[kTurnLanes], tdz[kTurnLanes];  // and direction
  alignas(32) float R[kTurnLanes];
  alignas(32) int32_t reflect[kTurnLanes], refract[kTurnLanes];
};

void secondary_rays(const TurningPoints& points, SecondaryRays* out);

}  // namespace tessera

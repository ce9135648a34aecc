// SPDX-License-Identifier: Apache-2.0
// The sphere test of a packet's lanes at once (structure of arrays, Google Highway at the
// machine's width, picked at run time): for each active lane, the nearest root of
// intersect_sphere() (render/sphere.h) in (tnear, tfar), the sphere geometry's callbacks' rule
// (sphere_geometry.cpp, sphere_root()), in the same double operations in the same order, never
// fused, so every lane's root is bit for bit the scalar one (sphere_test.cpp checks every target).
//
// Why: Embree calls a sphere's callback once for all the lanes of a packet whose rays reach its
// box, and a lane's roots are three double square roots and a division: one lane at a time they
// were a tenth of a Whitted frame (docs/performance.md, "Packets and SIMD stages").
#pragma once

#include <cstdint>

#include "math/vec3.h"

namespace tessera {

inline constexpr int kSphereLanes = 8;  // the packet width Embree calls back with (rtcIntersect8)

// One packet's rays, as Embree's RTCRay8 holds them (float arrays of 8), and what the test needs
// to know of each lane.
struct SphereLanes {
  const float *ox, *oy, *oz, *dx, *dy, *dz, *tnear, *tfar;
  const int32_t* active;   // 1: test this lane; 0: leave it (t = -1)
  const int32_t* leaving;  // 1: the ray leaves this sphere's surface (only an inward far root counts)
};

// t[i]: lane i's nearest acceptable root, or -1 (none, or an inactive lane).
void sphere_roots(const SphereLanes& lanes, const Vec3d& center, double radius, double t[kSphereLanes]);

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Which of a packet's rays pass near enough to each sphere of a small scene to meet it: the
// float test that lets RenderScene scan a few spheres directly instead of traversing a BVH
// (render_scene_scan.cpp). Google Highway at the machine's width, picked at run time.
//
// It is conservative, not exact: a lane it leaves out provably misses the sphere (its line
// passes farther from the centre than the radius, or the whole sphere lies behind the origin),
// by margins far above the float test's rounding error; every lane it keeps goes on to the exact
// double test (render/sphere_roots.h), which alone decides the hit. So it changes no answer,
// only how many spheres the exact test runs on.
#pragma once

#include <cstddef>
#include <cstdint>

namespace tessera {

struct RayArrays;

inline constexpr size_t kScanSpheres = 8;  // the most spheres a scene is scanned with
inline constexpr size_t kScanLanes = 8;    // a packet's rays (RenderScene::kPacket)

// The spheres, as the test reads them: centre and reach (the radius widened by the margin of the
// test's own rounding for origins within a bound, sphere_scan_simd.cpp), in float.
struct ScanTable {
  alignas(32) float cx[kScanSpheres] = {}, cy[kScanSpheres] = {}, cz[kScanSpheres] = {};
  alignas(32) float reach[kScanSpheres] = {};
  size_t count = 0;
};

// One sphere's entry: its centre and radius in render space (double, as the exact test takes
// them), for rays whose origins o have |o.x| + |o.y| + |o.z| <= `origins`.
void add_scan_sphere(ScanTable* table, double cx, double cy, double cz, double radius, double origins);

// near[s], for each sphere s < table.count: bit i set when lane i is in `lanes` and its ray may
// meet sphere s at some t > 0. The origins of the lanes in `lanes` must lie within the table's
// bound (add_scan_sphere).
void scan_candidates(const RayArrays& rays, const ScanTable& table, uint32_t lanes, uint32_t* near);

}  // namespace tessera

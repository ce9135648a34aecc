// SPDX-License-Identifier: Apache-2.0
// How a RenderScene is built: which ray-triangle test it traces with, and how it finds spheres.
#pragma once

#include <cstdint>

namespace tessera {

// How rays meet triangles (docs/accuracy.md, case 4, has the leak counts and costs).
enum class TriangleTest : uint8_t {
  // Default. Woop, Benthin and Wald's watertight test with double edge functions
  // (render/watertight_triangle.h), as Embree user geometry in clusters of 8 tested in SIMD
  // (render/triangle_cluster.h): no ray passes between the triangles of a closed mesh, at edges
  // or vertices.
  kWatertight,
  // Embree's RTC_SCENE_FLAG_ROBUST (Pluecker) test: closed along shared edges, but a ray aimed
  // at a shared vertex can miss the whole fan. About 2x faster per triangle-bound ray.
  kEmbreeRobust,
  // Embree's default test: the fastest; leaks along edges and at vertices.
  kEmbreeFast,
};

// "watertight", "embree-robust", "embree-fast" (benchmarks' --triangles).
constexpr const char* triangle_test_name(TriangleTest t) {
  return t == TriangleTest::kWatertight ? "watertight" : t == TriangleTest::kEmbreeRobust ? "embree-robust" : "embree-fast";
}

// How rays find the spheres of a scene without triangles.
enum class SphereSearch : uint8_t {
  // Default. A scene of at most kScanSpheres (render/sphere_scan.h) spheres and no triangles is
  // scanned: each packet of rays tested against every sphere the float test of
  // render/sphere_scan.h keeps (render_scene_scan.cpp). Any other scene: Embree's BVH.
  kScanSmall,
  // Always Embree's BVH (the tests and benchmarks compare the two: the same answers).
  kEmbree,
};

// "scan", "embree" (benchmarks' --spheres).
constexpr const char* sphere_search_name(SphereSearch s) { return s == SphereSearch::kScanSmall ? "scan" : "embree"; }

struct RenderOptions {
  TriangleTest triangles = TriangleTest::kWatertight;
  SphereSearch spheres = SphereSearch::kScanSmall;
};

}  // namespace tessera

// Triangles in clusters of up to 8, each cluster one Embree user primitive whose callback runs the
// watertight test (render/watertight_triangle.h) on all its triangles at once, in SIMD.
//
// Why: with one user primitive per triangle, Embree calls back once per triangle a ray's
// traversal reaches, and a mesh-bound ray reaches dozens; the calls, not the arithmetic, made the
// watertight test cost 1.65x Embree's own per frame and made packets no faster than single rays
// (docs/performance.md). Embree's own triangles sit in leaves of 4-16 that one SIMD test covers;
// a cluster is the same idea for our test. The clusters are the leaves of a SAH BVH that Embree's
// own builder (rtcBuildBVH) makes over the triangles, so they are spatially tight.
//
// The arithmetic is the scalar test's, lane for lane: the same float shear, the same exact
// double edge functions and the same rounding of t, u and v. Only IEEE add, subtract, multiply,
// divide and float-to-double conversion are used, never fused, so every SIMD target (SSE4,
// AVX2, AVX-512, chosen at run time by Google Highway) gives the scalar test's bits
// (triangle_cluster_test.cpp checks it on every target this machine supports).
#pragma once

#include <cstdint>
#include <vector>

#include "math/vec3.h"
#include "render/watertight_triangle.h"

namespace tessera {

struct alignas(64) TriangleCluster {
  static constexpr int kSize = 8;
  float v[3][3][kSize];    // [vertex][axis][lane]; unused lanes hold a degenerate triangle (0, 0, 0)
  uint32_t tri[kSize];     // the lane's triangle index in its bucket; unused lanes: UINT32_MAX
  uint32_t count = 0;      // lanes in use, 1..kSize
  Vec3f lower, upper;      // bounds of the cluster's triangles (unpadded)
};

// Groups `count` triangles (3 unshared vertices each in `positions`) into clusters: the leaves of
// an Embree SAH BVH with at most kSize triangles per leaf, ordered by their first triangle index
// so the result does not depend on the builder's threads.
std::vector<TriangleCluster> build_triangle_clusters(const Vec3f* positions, size_t count);

// The cluster's triangles the ray o + t d meets within [tnear, tfar], by the watertight test:
// bit k of the result set when lane k hits, its t, u, v in hit[k] (exactly what
// intersect_triangle_watertight returns for that triangle). Lane `skip` (or none: -1) is left
// out: the triangle the ray leaves.
uint32_t intersect_cluster(const TriangleCluster& c, const Vec3f& o, const RayShear& s, float tnear, float tfar,
                           int skip, TriangleHit hit[TriangleCluster::kSize]);

}  // namespace tessera

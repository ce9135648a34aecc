// SPDX-License-Identifier: Apache-2.0
// Triangles in clusters of up to 8, each cluster one Embree user primitive whose callback runs the
// watertight test (render/watertight_triangle.h) on all its triangles at once, in SIMD.
//
// Why: with one user primitive per triangle, Embree calls back once per triangle a ray's traversal
// reaches, and a mesh-bound ray reaches dozens; the calls, not the arithmetic, made the watertight
// test cost 1.65x Embree's own per frame and made packets no faster than single rays
// (docs/performance.md, "Watertight triangle clusters"). Embree's own triangles sit in leaves of
// 4-16 that one SIMD test covers; a cluster is the same idea for our test. The clusters are the
// leaves of a SAH BVH that Embree's own builder (rtcBuildBVH) makes over the triangles, so they are
// spatially tight.
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

// A ray as the cluster test takes it: its shear and its origin in the shear's axis order. Both
// depend on the ray alone; intersect_cluster_packet makes them for a packet's lanes at once.
struct ClusterRay {
  RayShear s;
  float ox, oy, oz;  // o[s.kx], o[s.ky], o[s.kz]
};

inline ClusterRay cluster_ray(const Vec3f& o, const Vec3f& d) {
  const RayShear s = ray_shear(d);
  return {s, o[s.kx], o[s.ky], o[s.kz]};
}

// The cluster's triangles the ray meets within [tnear, tfar], by the watertight test: bit k of
// the result set when lane k hits, its t, u, v in hit[k] (exactly what
// intersect_triangle_watertight returns for that triangle with the ray's shear). The lane whose
// triangle index is `skip` (UINT32_MAX: none) is left out: the triangle the ray leaves.
uint32_t intersect_cluster(const TriangleCluster& c, const ClusterRay& r, float tnear, float tfar, uint32_t skip,
                           TriangleHit hit[TriangleCluster::kSize]);

// A packet of N rays as Embree lays them out for a callback (RTCRayN): lane i's field f at f[i].
struct ClusterPacket {
  static constexpr unsigned kMaxLanes = 16;  // Embree's widest packet
  const float *org_x, *org_y, *org_z, *dir_x, *dir_y, *dir_z, *tnear, *tfar;
  const uint32_t* mask;  // the rays' masks
  const int* valid;      // Embree's valid lanes (non-zero)
  uint32_t geom_mask;    // the geometry's mask: a lane is tested when valid and its mask meets it
  unsigned N;            // 1..kMaxLanes
  // The triangle lane i's ray leaves (UINT32_MAX: none): leaving(user, i). Asked only for a lane
  // the float pass leaves open, not for every lane and cluster a traversal reaches.
  uint32_t (*leaving)(const void* user, unsigned lane);
  const void* user;
};

// For each lane i to test (valid[i] != 0 and mask[i] & geom_mask != 0): masks[i] and hit[i] exactly as
// intersect_cluster(c, cluster_ray(o_i, d_i), tnear_i, tfar_i, p.leaving(p.user, i), hit[i])
// gives them; other lanes' entries are left alone. Returns the lanes with a hit (bit i:
// masks[i] != 0).
//
// Why a packet call: Embree calls a cluster back once for all the packet's lanes that reach it
// (on the glTF scene 5.4 on average), and per lane the callback paid the shear (three divisions,
// an axis choice) and Highway's dispatch (a call into libhwy). Here the lanes' shears are one
// vector computation, and so are the lanes to test; the dispatch is once per callback.
uint32_t intersect_cluster_packet(const TriangleCluster& c, const ClusterPacket& p, uint32_t* masks,
                                  TriangleHit (*hit)[TriangleCluster::kSize]);

}  // namespace tessera

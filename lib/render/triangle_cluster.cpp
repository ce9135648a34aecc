// SPDX-License-Identifier: Apache-2.0
#include "render/triangle_cluster.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <limits>
#include <mutex>

#include "render/embree_device.h"

namespace tessera {

namespace {

// The builder's callbacks: only the leaves are kept (as clusters); inner nodes are the minimum
// Embree needs to run its builder.
struct Leaves {
  std::mutex mutex;  // createLeaf runs on the builder's threads
  std::vector<std::vector<uint32_t>> leaves;
};

void* create_node(RTCThreadLocalAllocator alloc, unsigned int, void*) { return rtcThreadLocalAlloc(alloc, 8, 8); }
void set_children(void*, void**, unsigned int, void*) {}
void set_bounds(void*, const RTCBounds**, unsigned int, void*) {}
void* create_leaf(RTCThreadLocalAllocator alloc, const RTCBuildPrimitive* prims, size_t n, void* user) {
  std::vector<uint32_t> ids(n);
  for (size_t i = 0; i < n; ++i) ids[i] = prims[i].primID;
  std::sort(ids.begin(), ids.end());
  auto* out = static_cast<Leaves*>(user);
  {
    std::lock_guard lock(out->mutex);
    out->leaves.push_back(std::move(ids));
  }
  return rtcThreadLocalAlloc(alloc, 8, 8);
}

}  // namespace

std::vector<TriangleCluster> build_triangle_clusters(const Vec3f* positions, size_t count) {
  constexpr int K = TriangleCluster::kSize;
  // Capacity = count: the builder needs spare capacity only for spatial splits, and none are asked for.
  std::vector<RTCBuildPrimitive> prims(count);
  for (size_t i = 0; i < count; ++i) {
    const Vec3f* v = positions + 3 * i;
    const Vec3f lo = vmin(v[0], vmin(v[1], v[2])), hi = vmax(v[0], vmax(v[1], v[2]));
    prims[i] = {lo.x, lo.y, lo.z, 0u, hi.x, hi.y, hi.z, uint32_t(i)};
  }
  Leaves leaves;
  if (count > 0) {
    RTCBVH bvh = rtcNewBVH(embree_device());
    RTCBuildArguments args = rtcDefaultBuildArguments();
    args.buildQuality = RTC_BUILD_QUALITY_MEDIUM;
    args.maxBranchingFactor = 2;
    // A leaf costs one SIMD test whether it holds 1 or 8 triangles: the SAH counts triangles in
    // blocks of 8, so it fills leaves unless splitting them pays.
    args.sahBlockSize = K;
    args.minLeafSize = 1;
    args.maxLeafSize = K;
    args.traversalCost = 1.0f;
    args.intersectionCost = 1.0f;
    args.bvh = bvh;
    args.primitives = prims.data();
    args.primitiveCount = prims.size();
    args.primitiveArrayCapacity = prims.capacity();
    args.createNode = create_node;
    args.setNodeChildren = set_children;
    args.setNodeBounds = set_bounds;
    args.createLeaf = create_leaf;
    args.userPtr = &leaves;
    rtcBuildBVH(&args);
    rtcReleaseBVH(bvh);
    check_embree("clustering triangles");
  }
  // Leaves come in the order the builder's threads made them: sort for a deterministic layout.
  std::sort(leaves.leaves.begin(), leaves.leaves.end());
  std::vector<TriangleCluster> clusters;
  for (const auto& ids : leaves.leaves) {
    // Embree may make a leaf of more than maxLeafSize only for identical boxes; split those.
    for (size_t first = 0; first < ids.size(); first += K) {
      TriangleCluster c{};
      c.count = uint32_t(std::min<size_t>(K, ids.size() - first));
      c.lower = Vec3f(std::numeric_limits<float>::infinity());
      c.upper = Vec3f(-std::numeric_limits<float>::infinity());
      for (int lane = 0; lane < K; ++lane) {
        c.tri[lane] = UINT32_MAX;
        if (uint32_t(lane) >= c.count) continue;
        const uint32_t t = ids[first + size_t(lane)];
        c.tri[lane] = t;
        for (int k = 0; k < 3; ++k) {
          const Vec3f& p = positions[3 * size_t(t) + size_t(k)];
          c.v[k][0][lane] = p.x;
          c.v[k][1][lane] = p.y;
          c.v[k][2][lane] = p.z;
          c.lower = vmin(c.lower, p);
          c.upper = vmax(c.upper, p);
        }
      }
      clusters.push_back(c);
    }
  }
  return clusters;
}

}  // namespace tessera

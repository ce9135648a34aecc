// SPDX-License-Identifier: Apache-2.0
// The watertight test's triangle clusters (render/triangle_cluster.h) as Embree user geometry:
// one user primitive per cluster of up to 8 triangles, whose callbacks test all of them at once.
#include <cstdint>
#include <limits>
#include <utility>

#include "render/isa_clones.h"
#include "render/render_scene_embree.h"
#include "render/triangle_cluster.h"
#include "render/user_geometry.h"
#include "render/watertight_triangle.h"

namespace tessera {

namespace {

using TraceContext = RenderScene::TraceContext;
using TriangleGeomData = RenderScene::TriangleGeomData;

// Vertex j of the triangle in lane k: the cluster holds the bucket's vertices, the same floats,
// already in cache during traversal (the bucket's positions array, on a large mesh, is not).
Vec3f cluster_vertex(const TriangleCluster& c, int j, int k) { return {c.v[j][0][k], c.v[j][1][k], c.v[j][2][k]}; }

// A user primitive is a cluster of up to 8 triangles (render/triangle_cluster.h).
void cluster_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* data = static_cast<const TriangleGeomData*>(args->geometryUserPtr);
  const TriangleCluster& c = data->bucket->clusters[args->primID];
  set_padded_bounds(args->bounds_o, c.lower, c.upper, *data->scene);
}

// What leaving() needs to find the triangle a lane's ray leaves.
struct LeavingArgs {
  const TriangleGeomData* data;
  const TraceContext* ctx;
  RTCRayN* ray;
  unsigned N;
};

// The triangle lane i's ray leaves, if it is one of this bucket's (else UINT32_MAX): left out of
// the test (a flat primitive cannot be met again: excluded exactly, like planes and spheres).
uint32_t leaving(const void* user, unsigned i) {
  const auto* a = static_cast<const LeavingArgs*>(user);
  const PrimRef& from = a->ctx->from_of(a->ray, a->N, i);
  return from.kind == PrimRef::Kind::kTriangle && from.geom == a->data->bucket_index ? from.id : UINT32_MAX;
}

// The watertight test of a packet's valid lanes against a cluster (intersect_cluster_packet, one
// call for all of them): returns the lanes that hit, masks[i] the triangles lane i hits (set only
// for those lanes).
uint32_t cluster_lanes(const TriangleGeomData* data, const TriangleCluster& c, const TraceContext* ctx,
                       const int* valid, RTCRayN* ray, unsigned N, uint32_t masks[ClusterPacket::kMaxLanes],
                       TriangleHit th[ClusterPacket::kMaxLanes][TriangleCluster::kSize]) {
  const LeavingArgs args{data, ctx, ray, N};
  const ClusterPacket p{&RTCRayN_org_x(ray, N, 0), &RTCRayN_org_y(ray, N, 0), &RTCRayN_org_z(ray, N, 0),
                        &RTCRayN_dir_x(ray, N, 0), &RTCRayN_dir_y(ray, N, 0), &RTCRayN_dir_z(ray, N, 0),
                        &RTCRayN_tnear(ray, N, 0), &RTCRayN_tfar(ray, N, 0), &RTCRayN_mask(ray, N, 0),
                        valid, data->mask, N, leaving, &args};
  return intersect_cluster_packet(c, p, masks, th);
}

TESSERA_ISA_CLONES void cluster_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* data = static_cast<const TriangleGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  const TriangleCluster& c = data->bucket->clusters[args->primID];
  const unsigned N = args->N;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, N);
  RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, N);
  uint32_t masks[ClusterPacket::kMaxLanes];
  TriangleHit th[ClusterPacket::kMaxLanes][TriangleCluster::kSize];
  for (uint32_t hit_lanes = cluster_lanes(data, c, ctx, args->valid, ray, N, masks, th); hit_lanes != 0;
       hit_lanes &= hit_lanes - 1) {
    const unsigned i = unsigned(__builtin_ctz(hit_lanes));
    // The cluster's hits in lane order, each as if its triangle were tested alone after the
    // ones before it: nearer than the nearest so far, and on an exact tie (a ray through a
    // shared edge or vertex) to the lower (geometry, triangle) id, so the result depends neither
    // on traversal order (packet or single ray, BVH layout) nor on how triangles are clustered.
    // (Lane i's test read its tfar before any of these writes, which touch lane i alone.)
    for (uint32_t m = masks[i]; m != 0; m &= m - 1) {
      const int k = __builtin_ctz(m);
      const TriangleHit& h = th[i][k];
      const float tfar = RTCRayN_tfar(ray, N, i);
      if (h.t > tfar) continue;
      if (h.t == tfar && RTCHitN_geomID(hit, N, i) != RTC_INVALID_GEOMETRY_ID &&
          std::pair(RTCHitN_geomID(hit, N, i), RTCHitN_primID(hit, N, i)) < std::pair(args->geomID, c.tri[k])) {
        continue;
      }
      const Vec3f v0 = cluster_vertex(c, 0, k), v1 = cluster_vertex(c, 1, k), v2 = cluster_vertex(c, 2, k);
      record_hit(args, i, h.t, cross(v1 - v0, v2 - v0), h.u, h.v, c.tri[k]);
    }
  }
}

TESSERA_ISA_CLONES void cluster_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const TriangleGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  const TriangleCluster& c = data->bucket->clusters[args->primID];
  const unsigned N = args->N;
  RTCRayN* ray = args->ray;
  uint32_t masks[ClusterPacket::kMaxLanes];
  TriangleHit th[ClusterPacket::kMaxLanes][TriangleCluster::kSize];
  for (uint32_t hit_lanes = cluster_lanes(data, c, ctx, args->valid, ray, N, masks, th); hit_lanes != 0;
       hit_lanes &= hit_lanes - 1) {
    const unsigned i = unsigned(__builtin_ctz(hit_lanes));
    const uint32_t m = masks[i];
    if (ctx->glass && data->mask == RenderScene::kGlassMask) {
      // A shadow ray collecting glass crossings (see sphere_occluded(), sphere_geometry.cpp):
      // record, go on.
      for (uint32_t r = m; r != 0; r &= r - 1) {
        const int k = __builtin_ctz(r);
        ctx->glass[RTCRayN_id(ray, N, i)].add(th[i][k].t, data->bucket->material_ids[c.tri[k]]);
      }
      continue;
    }
    RTCRayN_tfar(ray, N, i) = -std::numeric_limits<float>::infinity();
  }
}

}  // namespace

uint32_t attach_triangle_clusters(RTCScene scene, TriangleGeomData* data) {
  return attach_user_geometry(scene, data->bucket->clusters.size(), data, cluster_bounds, cluster_intersect,
                              cluster_occluded, data->mask);
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Embree user geometry: primitives whose callbacks run our own tests. The watertight test's
// triangle clusters (cluster_geometry.cpp) and the spheres (sphere_geometry.cpp) are attached to
// the Embree scene here, and share padded bounding boxes and the hit record a callback writes.
#pragma once

#include <cstddef>
#include <cstdint>

#include "math/vec3.h"
#include "render/embree_device.h"
#include "render/render_scene_internal.h"

namespace tessera {

// The user geometry of data's bucket (its clusters, its spheres), attached to `scene` with data as
// its callbacks' user data; returns its geometry id.
uint32_t attach_triangle_clusters(RTCScene scene, RenderScene::TriangleGeomData* data);
uint32_t attach_spheres(RTCScene scene, RenderScene::SphereGeomData* data);

// Sets *b to [lo, hi] padded by scene.box_padding() (why, in user_geometry.cpp), rounded outward.
void set_padded_bounds(RTCBounds* b, const Vec3f& lo, const Vec3f& hi, const RenderScene& scene);

// Writes lane i's new closest hit, as Embree's own primitives would; `prim` is the primitive id
// the hit reports (a clustered triangle reports its own index, not its cluster's).
inline void record_hit(const RTCIntersectFunctionNArguments* args, unsigned i, float t, const Vec3f& ng, float u,
                       float v, uint32_t prim) {
  const unsigned N = args->N;
  RTCRayN_tfar(RTCRayHitN_RayN(args->rayhit, N), N, i) = t;
  RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, N);
  RTCHitN_Ng_x(hit, N, i) = ng.x;
  RTCHitN_Ng_y(hit, N, i) = ng.y;
  RTCHitN_Ng_z(hit, N, i) = ng.z;
  RTCHitN_u(hit, N, i) = u;
  RTCHitN_v(hit, N, i) = v;
  RTCHitN_primID(hit, N, i) = prim;
  RTCHitN_geomID(hit, N, i) = args->geomID;
  RTCHitN_instID(hit, N, i, 0) = args->context->instID[0];
}

// One user geometry of `count` primitives whose callbacks run our own tests; returns its id.
uint32_t attach_user_geometry(RTCScene scene, size_t count, void* data, RTCBoundsFunction bounds,
                              RTCIntersectFunctionN intersect, RTCOccludedFunctionN occluded, uint32_t mask);

}  // namespace tessera

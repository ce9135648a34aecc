// SPDX-License-Identifier: Apache-2.0
#include "render/user_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/render_scene_internal.h"

namespace tessera {

// Embree's box test for user geometry is not conservative (RTC_SCENE_FLAG_ROBUST's conservative
// traversal applies to its built-in triangles only; measured: unpadded boxes let 4933 of 81,936
// vertex-aimed rays miss an icosphere whose triangle test is exact). Its slab distances
// fl(lower * rdir - fl(org * rdir)) use an approximate reciprocal rdir, so each is off by about
// (2u + e_rcp)(|org| + |lower|) in distance along an axis, e_rcp <= 2^-22: at most
// 2^-21 (|org| + |box|). Padding every box by 2^-16 (|box| + R), R = the radius of the
// triangles around the eye, covers that with a factor 32 for every ray starting within 32 R of
// the eye: all camera rays (they start at the eye) and all rays leaving triangles or spheres
// no bigger than the triangles' reach. A ray starting beyond 16 times the radius of all bounded
// geometry (only a ray leaving an infinite plane can) is moved to start near the geometry first
// (RenderScene::embree_ray). Padding only adds candidates; the primitive tests decide, so it
// cannot change a pixel, only cost a little culling.
void set_padded_bounds(RTCBounds* b, const Vec3f& lo, const Vec3f& hi, const RenderScene& scene) {
  const float pad = scene.box_padding(std::max(max_component(abs(lo)), max_component(abs(hi))));
  const float inf = std::numeric_limits<float>::infinity();
  // Rounded outward, so the padded box contains [lo, hi] even where pad is below an ulp.
  b->lower_x = std::nextafter(lo.x - pad, -inf);
  b->lower_y = std::nextafter(lo.y - pad, -inf);
  b->lower_z = std::nextafter(lo.z - pad, -inf);
  b->upper_x = std::nextafter(hi.x + pad, inf);
  b->upper_y = std::nextafter(hi.y + pad, inf);
  b->upper_z = std::nextafter(hi.z + pad, inf);
}

uint32_t attach_user_geometry(RTCScene scene, size_t count, void* data, RTCBoundsFunction bounds,
                              RTCIntersectFunctionN intersect, RTCOccludedFunctionN occluded, uint32_t mask) {
  GeometryHandle g(rtcNewGeometry(embree_device(), RTC_GEOMETRY_TYPE_USER));
  rtcSetGeometryUserPrimitiveCount(g.get(), unsigned(count));
  rtcSetGeometryUserData(g.get(), data);
  rtcSetGeometryBoundsFunction(g.get(), bounds, nullptr);
  rtcSetGeometryIntersectFunction(g.get(), intersect);
  rtcSetGeometryOccludedFunction(g.get(), occluded);
  rtcSetGeometryMask(g.get(), mask);
  rtcCommitGeometry(g.get());
  return rtcAttachGeometry(scene, g.get());
}

}  // namespace tessera

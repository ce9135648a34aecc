// SPDX-License-Identifier: Apache-2.0
// The Embree scene of a RenderScene, built over its buckets: the watertight test's clusters and
// the spheres as user geometry (cluster_geometry.cpp, sphere_geometry.cpp), or, with the
// embree-robust and embree-fast tests, Embree's own triangles on the buckets' vertices.
#include <vector>

#include "render/render_scene_embree.h"
#include "render/triangle_cluster.h"
#include "render/user_geometry.h"

namespace tessera {

namespace {

// Occlusion filter of Embree's own glass triangles: while a shadow ray collects glass crossings,
// record the candidate and reject it so traversal goes on (Embree sets tfar to the candidate's
// t). Its user data is the bucket's material ids.
void glass_triangle_occluded_filter(const RTCFilterFunctionNArguments* args) {
  const auto* ctx = reinterpret_cast<const RenderScene::TraceContext*>(args->context);
  if (!ctx->glass) return;
  const auto& material_ids = *static_cast<const std::vector<uint32_t>*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    ctx->glass[RTCRayN_id(args->ray, args->N, i)].add(RTCRayN_tfar(args->ray, args->N, i),
                                                      material_ids[RTCHitN_primID(args->hit, args->N, i)]);
    args->valid[i] = 0;
  }
}

}  // namespace

void RenderScene::ReleaseEmbreeScene::operator()(RTCSceneTy* scene) const { rtcReleaseScene(scene); }

void RenderScene::build_embree_scene() {
  RTCDevice device = embree_device();
  rtc_scene_.reset(rtcNewScene(device));
  RTCScene s = rtc_scene_.get();
  rtcSetSceneFlags(s, options_.triangles == TriangleTest::kEmbreeRobust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(s, RTC_BUILD_QUALITY_MEDIUM);  // deterministic (HIGH is not)
  user_geometry_ = std::make_unique<UserGeometryData>();
  for (int k = 0; k < 2; ++k) {
    TriangleBucket& b = triangles_[k];
    if (b.material_ids.empty()) continue;
    if (options_.triangles == TriangleTest::kWatertight) {
      TriangleGeomData& data = user_geometry_->triangles[k];
      data = {this, &b, uint32_t(k), k == 0 ? kOpaqueMask : kGlassMask};
      b.clusters = build_triangle_clusters(b.positions.data(), b.material_ids.size());
      b.geom_id = attach_triangle_clusters(s, &data);
      continue;
    }
    const size_t nv = b.positions.size();
    b.positions.push_back(Vec3f(0.0f));  // padding for Embree's 16-byte vertex loads
    GeometryHandle g(rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE));
    rtcSetSharedGeometryBuffer(g.get(), RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, b.positions.data(), 0,
                               sizeof(Vec3f), nv);
    rtcSetSharedGeometryBuffer(g.get(), RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, b.indices.data(), 0,
                               3 * sizeof(uint32_t), b.material_ids.size());
    rtcSetGeometryMask(g.get(), k == 0 ? kOpaqueMask : kGlassMask);
    if (k == 1) {
      rtcSetGeometryUserData(g.get(), &b.material_ids);
      rtcSetGeometryOccludedFilterFunction(g.get(), glass_triangle_occluded_filter);
    }
    rtcCommitGeometry(g.get());
    b.geom_id = rtcAttachGeometry(s, g.get());
  }
  for (int k = 0; k < 2; ++k) {
    SphereBucket& b = sphere_buckets_[k];
    if (b.ids.empty()) continue;
    b.mask = k == 0 ? kOpaqueMask : kGlassMask;
    SphereGeomData& data = user_geometry_->spheres[k];
    data = {this, &b};
    b.geom_id = attach_spheres(s, &data);
  }
  rtcCommitScene(s);
  check_embree("building the Embree scene");
}

}  // namespace tessera

#include "render/render_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "math/transform.h"
#include "render/plane.h"
#include "render/ray_log.h"
#include "render/shading_normal.h"
#include "render/sphere.h"
#include "render/triangle_cluster.h"
#include "render/watertight_triangle.h"
#include "scene/animation.h"
#include "scene/texture_sample.h"

namespace tessera {

namespace {

constexpr uint32_t kOpaqueMask = RenderScene::kOpaqueMask;
constexpr uint32_t kGlassMask = RenderScene::kGlassMask;
constexpr int kMaxGlassCrossings = 256;
constexpr double kDoubleEps = 0x1p-52;

using TraceContext = RenderScene::TraceContext;

// The primitive lane i's ray leaves (per lane for packets, see TraceContext).
const PrimRef& from_of(const TraceContext* ctx, RTCRayN* ray, unsigned N, unsigned i) {
  return ctx->from_by_id ? ctx->from_by_id[RTCRayN_id(ray, N, i)] : ctx->from;
}

void add_glass_hit(RenderScene::GlassHits* g, float t, uint32_t material) {
  if (g->count == RenderScene::kMaxGlassHits) {
    g->overflow = true;
    return;
  }
  g->hits[g->count++] = {t, material};
}

using SphereGeomData = RenderScene::SphereGeomData;
using TriangleGeomData = RenderScene::TriangleGeomData;

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

// Writes lane i's new closest hit, as Embree's own primitives would; `prim` is the primitive id
// the hit reports (a clustered triangle reports its own index, not its cluster's).
void record_hit(const RTCIntersectFunctionNArguments* args, unsigned i, float t, const Vec3f& ng, float u, float v,
                uint32_t prim) {
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

// Vertex j of the triangle in lane k: the cluster holds the bucket's vertices, the same floats,
// already in cache during traversal (the bucket's positions array, on a large mesh, is not).
Vec3f cluster_vertex(const TriangleCluster& c, int j, int k) { return {c.v[j][0][k], c.v[j][1][k], c.v[j][2][k]}; }

// A user primitive is a cluster of up to 8 triangles (render/triangle_cluster.h).
void cluster_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* data = static_cast<const TriangleGeomData*>(args->geometryUserPtr);
  const TriangleCluster& c = data->bucket->clusters[args->primID];
  set_padded_bounds(args->bounds_o, c.lower, c.upper, *data->scene);
}

// The watertight test of lane i against a cluster: the mask of its triangles hit, or 0 when the
// lane is masked out. The triangle the ray leaves is left out (a flat primitive cannot be met
// again: excluded exactly, like planes and spheres).
uint32_t cluster_lane(const TriangleGeomData* data, const TriangleCluster& c, const TraceContext* ctx, RTCRayN* ray,
                      unsigned N, unsigned i, TriangleHit th[TriangleCluster::kSize]) {
  if (!(RTCRayN_mask(ray, N, i) & data->mask)) return 0;
  const PrimRef& from = from_of(ctx, ray, N, i);
  int skip = -1;
  if (from.kind == PrimRef::Kind::kTriangle && from.geom == data->bucket_index) {
    for (uint32_t k = 0; k < c.count; ++k) {
      if (c.tri[k] == from.id) skip = int(k);
    }
  }
  const Vec3f o(RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i));
  const Vec3f d(RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i));
  return intersect_cluster(c, o, ray_shear(d), RTCRayN_tnear(ray, N, i), RTCRayN_tfar(ray, N, i), skip, th);
}

void cluster_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* data = static_cast<const TriangleGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  const TriangleCluster& c = data->bucket->clusters[args->primID];
  const unsigned N = args->N;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, N);
  RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, N);
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i]) continue;
    TriangleHit th[TriangleCluster::kSize];
    // The cluster's hits in lane order, each as if its triangle were tested alone after the
    // ones before it: nearer than the nearest so far, and on an exact tie (a ray through a
    // shared edge or vertex) to the lower (geometry, triangle) id, so the result depends neither
    // on traversal order (packet or single ray, BVH layout) nor on how triangles are clustered.
    for (uint32_t m = cluster_lane(data, c, ctx, ray, N, i, th); m != 0; m &= m - 1) {
      const int k = __builtin_ctz(m);
      const float tfar = RTCRayN_tfar(ray, N, i);
      if (th[k].t > tfar) continue;
      if (th[k].t == tfar && RTCHitN_geomID(hit, N, i) != RTC_INVALID_GEOMETRY_ID &&
          std::pair(RTCHitN_geomID(hit, N, i), RTCHitN_primID(hit, N, i)) < std::pair(args->geomID, c.tri[k])) {
        continue;
      }
      const Vec3f v0 = cluster_vertex(c, 0, k), v1 = cluster_vertex(c, 1, k), v2 = cluster_vertex(c, 2, k);
      record_hit(args, i, th[k].t, cross(v1 - v0, v2 - v0), th[k].u, th[k].v, c.tri[k]);
    }
  }
}

void cluster_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const TriangleGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  const TriangleCluster& c = data->bucket->clusters[args->primID];
  const unsigned N = args->N;
  RTCRayN* ray = args->ray;
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i]) continue;
    TriangleHit th[TriangleCluster::kSize];
    const uint32_t m = cluster_lane(data, c, ctx, ray, N, i, th);
    if (m == 0) continue;
    if (ctx->glass && data->mask == kGlassMask) {
      // A shadow ray collecting glass crossings (see sphere_occluded): record, go on.
      for (uint32_t r = m; r != 0; r &= r - 1) {
        const int k = __builtin_ctz(r);
        add_glass_hit(&ctx->glass[RTCRayN_id(ray, N, i)], th[k].t, data->bucket->material_ids[c.tri[k]]);
      }
      continue;
    }
    RTCRayN_tfar(ray, N, i) = -std::numeric_limits<float>::infinity();
  }
}

Transform object_transform(const TransformDesc& t) {
  if (t.matrix) return Transform::affine(*t.matrix);
  return Transform::translate(t.translate) * Transform::rotate_xyz_deg(t.rotate_deg) * Transform::scale(t.scale);
}

Vec3f round_down(const Vec3d& v) {
  Vec3f f(v);
  for (int i = 0; i < 3; ++i) {
    if (double(f[i]) > v[i]) f[i] = std::nextafter(f[i], -std::numeric_limits<float>::infinity());
  }
  return f;
}
Vec3f round_up(const Vec3d& v) {
  Vec3f f(v);
  for (int i = 0; i < 3; ++i) {
    if (double(f[i]) < v[i]) f[i] = std::nextafter(f[i], std::numeric_limits<float>::infinity());
  }
  return f;
}

void sphere_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* data = static_cast<const SphereGeomData*>(args->geometryUserPtr);
  const auto& s = data->scene->spheres()[data->bucket->ids[args->primID]];
  set_padded_bounds(args->bounds_o, round_down(s.center - Vec3d(s.radius)), round_up(s.center + Vec3d(s.radius)),
                    *data->scene);
}

// The nearest acceptable root of sphere `index` for a ray in (tnear, tfar), or -1.
double sphere_root(const RenderScene::Sphere& s, uint32_t index, const PrimRef& from, const Vec3d& o,
                   const Vec3d& d, float tnear, float tfar) {
  double t[2];
  if (intersect_sphere(o, d, s.center, s.radius, t) == 0) return -1;
  int first = 0;
  if (from.kind == PrimRef::Kind::kSphere && from.id == index) {
    // Leaving this sphere's surface: outward it cannot be met again (convex); inward, only
    // the far root is real. Exact, no epsilon.
    if (dot(d, o - s.center) >= 0) return -1;
    first = 1;
  }
  for (int i = first; i < 2; ++i) {
    const float tf = float(t[i]);
    if (tf > tnear && tf < tfar) return t[i];
  }
  return -1;
}

void sphere_intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* data = static_cast<const SphereGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  const unsigned N = args->N;
  const uint32_t index = data->bucket->ids[args->primID];
  const auto& s = data->scene->spheres()[index];
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i] || !(RTCRayN_mask(ray, N, i) & data->bucket->mask)) continue;
    const Vec3d o(RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i));
    const Vec3d d(RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i));
    const double t = sphere_root(s, index, from_of(ctx, ray, N, i), o, d, RTCRayN_tnear(ray, N, i),
                                 RTCRayN_tfar(ray, N, i));
    if (t < 0) continue;
    record_hit(args, i, float(t), Vec3f(o + d * t - s.center), 0.0f, 0.0f, args->primID);
  }
}

void sphere_occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* data = static_cast<const SphereGeomData*>(args->geometryUserPtr);
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  RTCRayN* ray = args->ray;
  const unsigned N = args->N;
  const uint32_t index = data->bucket->ids[args->primID];
  const auto& s = data->scene->spheres()[index];
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i] || !(RTCRayN_mask(ray, N, i) & data->bucket->mask)) continue;
    const Vec3d o(RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i));
    const Vec3d d(RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i));
    const PrimRef& from = from_of(ctx, ray, N, i);
    const float tnear = RTCRayN_tnear(ray, N, i), tfar = RTCRayN_tfar(ray, N, i);
    if (ctx->glass && data->bucket->mask == kGlassMask) {
      // A shadow ray collecting glass crossings: every root in (tnear, tfar), not just the first
      // (the same roots the old crossing-by-crossing walk found, in one traversal).
      double t[2];
      if (intersect_sphere(o, d, s.center, s.radius, t) == 0) continue;
      int first = 0;
      if (from.kind == PrimRef::Kind::kSphere && from.id == index) {
        if (dot(d, o - s.center) >= 0) continue;
        first = 1;
      }
      for (int k = first; k < 2; ++k) {
        const float tf = float(t[k]);
        if (tf > tnear && tf < tfar) add_glass_hit(&ctx->glass[RTCRayN_id(ray, N, i)], tf, s.material);
      }
      continue;
    }
    if (sphere_root(s, index, from, o, d, tnear, tfar) >= 0) {
      RTCRayN_tfar(ray, N, i) = -std::numeric_limits<float>::infinity();
    }
  }
}

// Occlusion filter of the glass triangles: while a shadow ray collects glass crossings, record
// the candidate and reject it so traversal goes on (Embree sets tfar to the candidate's t).
void glass_triangle_occluded_filter(const RTCFilterFunctionNArguments* args) {
  const auto* ctx = reinterpret_cast<const TraceContext*>(args->context);
  if (!ctx->glass) return;
  const auto* bucket = static_cast<const RenderScene::TriangleBucket*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    add_glass_hit(&ctx->glass[RTCRayN_id(args->ray, args->N, i)], RTCRayN_tfar(args->ray, args->N, i),
                  bucket->material_ids[RTCHitN_primID(args->hit, args->N, i)]);
    args->valid[i] = 0;
  }
}

// One user geometry of `count` primitives whose callbacks run our own tests; returns its id.
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

RTCRayHit make_rayhit(const Ray& ray, float tnear, float tfar, uint32_t mask) {
  RTCRayHit rh;
  rh.ray.org_x = ray.o.x;
  rh.ray.org_y = ray.o.y;
  rh.ray.org_z = ray.o.z;
  rh.ray.dir_x = ray.d.x;
  rh.ray.dir_y = ray.d.y;
  rh.ray.dir_z = ray.d.z;
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.time = 0.0f;
  rh.ray.mask = mask;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

}  // namespace

RenderScene::RenderScene(const Scene& scene, int frame, RenderOptions options) : options_(options) {
  build(scene, frame);
}

RenderScene::~RenderScene() {
  rtc_scene_.reset();  // before the geometry data its callbacks and shared buffers point into
}

RenderScene::Source RenderScene::source_of(const PrimRef& prim) const {
  switch (prim.kind) {
    case PrimRef::Kind::kTriangle: return triangles_[prim.geom].sources[prim.id];
    case PrimRef::Kind::kSphere: return {spheres_[prim.id].object, 0};
    case PrimRef::Kind::kPlane: return {planes_[prim.id].object, 0};
    case PrimRef::Kind::kNone: break;
  }
  return {};
}

size_t RenderScene::triangle_count() const {
  return triangles_[0].material_ids.size() + triangles_[1].material_ids.size();
}

void RenderScene::build(const Scene& scene, int frame) {
  image_ = scene.image;
  frame_ = frame;
  background_ = scene.background;
  materials_ = scene.materials;
  textures_ = scene.textures;
  const FrameState state = evaluate_frame(scene, frame);
  const ScreenPlane sp = screen_plane(state.camera, image_.width, image_.height);
  // Render space is world space shifted so the eye is the origin, computed in double and only
  // then rounded to float: precision follows the camera, so a scene far from the world origin
  // renders like the same scene at the origin (camera-relative rendering).
  origin_ = sp.eye;
  auto rel = [&](const Vec3d& p) { return p - origin_; };
  camera_ = {Vec3f(rel(sp.p0)), Vec3f(sp.p1 - sp.p0), Vec3f(sp.p2 - sp.p0)};

  for (const Light& l : scene.lights) {
    if (l.type == Light::Type::kPoint) {
      point_lights_.push_back({Vec3f(rel(l.position)), l.intensity});
    } else if (l.type == Light::Type::kSpot) {
      // KHR_lights_punctual's falloff: s = clamp(cos_angle * scale + offset, 0, 1), squared,
      // with scale = 1 / max(0.001, cos(inner) - cos(outer)), offset = -cos(outer) * scale:
      // 1 inside the inner cone, 0 outside the outer one.
      const double cos_outer = std::cos(l.outer_cone_rad), cos_inner = std::cos(l.inner_cone_rad);
      const double scale = 1.0 / std::max(0.001, cos_inner - cos_outer);
      spot_lights_.push_back({Vec3f(rel(l.position)), l.intensity, Vec3f(normalize(l.direction)), float(scale),
                              float(-cos_outer * scale)});
    } else {
      directional_lights_.push_back({Vec3f(normalize(l.direction)), l.irradiance});
    }
  }

  auto is_glass = [&](uint32_t m) { return materials_[m].type == Material::Type::kGlass; };
  for (size_t oi = 0; oi < scene.objects.size(); ++oi) {
    const SceneObject& obj = scene.objects[oi];
    const Transform xf = object_transform(state.transforms[oi]);
    switch (obj.type) {
      case SceneObject::Type::kSphere: {
        const uint32_t m = uint32_t(obj.material);
        const uint32_t index = uint32_t(spheres_.size());
        spheres_.push_back(
            {rel(xf.point(obj.center)), obj.radius * std::abs(state.transforms[oi].scale.x), m, uint32_t(oi)});
        sphere_buckets_[is_glass(m) ? 1 : 0].ids.push_back(index);
        break;
      }
      case SceneObject::Type::kPlane: {
        Plane p;
        p.point = rel(xf.point(obj.point));
        p.normal = normalize(xf.normal(obj.normal));
        orthonormal_basis(Vec3f(p.normal), p.b1, p.b2);
        p.material = uint32_t(obj.material);
        p.object = uint32_t(oi);
        planes_.push_back(p);
        break;
      }
      case SceneObject::Type::kMesh: {
        const Mesh& mesh = scene.meshes[size_t(obj.mesh)];
        const bool flip = xf.determinant() < 0;  // mirroring reverses winding: undo it
        std::vector<Vec3f> world(mesh.positions.size());
        for (size_t v = 0; v < mesh.positions.size(); ++v) world[v] = Vec3f(rel(xf.point(Vec3d(mesh.positions[v]))));
        std::map<uint32_t, size_t> light_of_material;
        for (size_t t = 0; t < mesh.triangle_count(); ++t) {
          const uint32_t m = mesh.material_ids[t];
          uint32_t i0 = mesh.indices[3 * t], i1 = mesh.indices[3 * t + 1], i2 = mesh.indices[3 * t + 2];
          if (flip) std::swap(i1, i2);
          const Vec3f a = world[i0], b = world[i1], c = world[i2];
          if (!(length(cross(b - a, c - a)) > 0)) continue;  // collapsed by float rounding or scale
          TriangleBucket& bucket = triangles_[is_glass(m) ? 1 : 0];
          const uint32_t base = uint32_t(bucket.positions.size());
          // Unshared vertices keep buckets simple; meshes here are small next to their BVH.
          bucket.positions.insert(bucket.positions.end(), {a, b, c});
          bucket.indices.insert(bucket.indices.end(), {base, base + 1, base + 2});
          bucket.material_ids.push_back(m);
          bucket.sources.push_back({uint32_t(oi), uint32_t(t)});
          if (materials_[m].albedo_texture >= 0 && !mesh.uvs.empty()) {
            // Only textured triangles store uv; the others' slots stay 0 (never read).
            bucket.uvs.resize(6 * (bucket.material_ids.size() - 1), 0.0f);
            for (uint32_t i : {i0, i1, i2}) bucket.uvs.insert(bucket.uvs.end(), {mesh.uvs[2 * i], mesh.uvs[2 * i + 1]});
          }
          if (mesh.normals.size() == mesh.positions.size()) {  // vertex normals: smooth shading (shading_normal.h)
            auto n = [&](uint32_t i) { return xf.normal(Vec3d(mesh.normals[i])); };
            append_vertex_normals(&bucket.normals, bucket.material_ids.size() - 1, {n(i0), n(i1), n(i2)});
          }
          if (materials_[m].is_emissive()) {
            auto [it, fresh] = light_of_material.try_emplace(m, area_lights_.size());
            if (fresh) area_lights_.push_back({{}, {}, 0.0f, materials_[m].emission});
            AreaLight& L = area_lights_[it->second];
            L.v.insert(L.v.end(), {a, b, c});
            L.area += 0.5f * length(cross(b - a, c - a));
            L.cdf.push_back(L.area);
          }
        }
        break;
      }
    }
  }
  for (TriangleBucket& b : triangles_) {
    if (!b.uvs.empty()) b.uvs.resize(6 * b.material_ids.size(), 0.0f);
    if (!b.normals.empty()) b.normals.resize(9 * b.material_ids.size(), 0.0f);
  }
  for (AreaLight& L : area_lights_) {
    for (float& c : L.cdf) c /= L.area;
    L.cdf.back() = 1.0f;
  }
  for (const Plane& p : planes_) {
    plane_table_.insert(plane_table_.end(), {p.point.x, p.point.y, p.point.z, p.normal.x, p.normal.y, p.normal.z});
    plane_ids_.insert(plane_ids_.end(), {p.material, p.object});
  }
  has_glass_ = !triangles_[1].material_ids.empty() || !sphere_buckets_[1].ids.empty();
  for (const Plane& p : planes_) has_glass_ = has_glass_ || is_glass(p.material);

  for (const TriangleBucket& b : triangles_) {
    for (const Vec3f& p : b.positions) triangle_radius_ = std::max(triangle_radius_, max_component(abs(p)));
    bounds_radius_ = triangle_radius_;
  }
  for (const Sphere& sp : spheres_) {
    bounds_radius_ = std::max(bounds_radius_, float(max_component(abs(sp.center)) + sp.radius));
  }

  RTCDevice device = embree_device();
  rtc_scene_ = SceneHandle(rtcNewScene(device));
  RTCScene s = rtc_scene_.get();
  rtcSetSceneFlags(s, options_.triangles == TriangleTest::kEmbreeRobust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(s, RTC_BUILD_QUALITY_MEDIUM);  // deterministic (HIGH is not)
  for (int k = 0; k < 2; ++k) {
    TriangleBucket& b = triangles_[k];
    if (b.material_ids.empty()) continue;
    if (options_.triangles == TriangleTest::kWatertight) {
      triangle_data_[k] = {this, &b, uint32_t(k), k == 0 ? kOpaqueMask : kGlassMask};
      b.clusters = build_triangle_clusters(b.positions.data(), b.material_ids.size());
      b.geom_id = attach_user_geometry(s, b.clusters.size(), &triangle_data_[k], cluster_bounds, cluster_intersect,
                                       cluster_occluded, triangle_data_[k].mask);
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
      rtcSetGeometryUserData(g.get(), &b);
      rtcSetGeometryOccludedFilterFunction(g.get(), glass_triangle_occluded_filter);
    }
    rtcCommitGeometry(g.get());
    b.geom_id = rtcAttachGeometry(s, g.get());
  }
  for (int k = 0; k < 2; ++k) {
    SphereBucket& b = sphere_buckets_[k];
    if (b.ids.empty()) continue;
    b.mask = k == 0 ? kOpaqueMask : kGlassMask;
    sphere_data_[k] = {this, &sphere_buckets_[k]};
    b.geom_id = attach_user_geometry(s, b.ids.size(), &sphere_data_[k], sphere_bounds, sphere_intersect,
                                     sphere_occluded, b.mask);
  }
  rtcCommitScene(s);
  check_embree("building the Embree scene");
}

double RenderScene::nearest_plane(const Vec3d& o, const Vec3d& d, const PrimRef& from, double tmax,
                                  int* which) const {
  double best = tmax;
  *which = -1;
  for (size_t i = 0; i < planes_.size(); ++i) {
    // A ray leaving a plane can never meet the same plane again: exclude it exactly.
    if (from.kind == PrimRef::Kind::kPlane && from.id == i) continue;
    const double t = intersect_plane(o, d, planes_[i].point, planes_[i].normal);
    if (t > 0.0 && t < best) {
      best = t;
      *which = int(i);
    }
  }
  return best;
}

double RenderScene::embree_ray_from_far(const Ray& ray, Ray* out) const {
  const double L = 2.0 * double(bounds_radius_);
  double t_in = 0.0, t_out = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const double o = ray.o[k], d = ray.d[k];
    if (d == 0.0) {
      if (std::abs(o) > L) return -1.0;
      continue;
    }
    const double a = (-L - o) / d, b = (L - o) / d;
    t_in = std::max(t_in, std::min(a, b));
    t_out = std::min(t_out, std::max(a, b));
  }
  if (!(t_in <= t_out) || !(t_in < double(ray.tmax))) return -1.0;
  out->o = Vec3f(Vec3d(ray.o) + Vec3d(ray.d) * t_in);
  out->tmax = float(double(ray.tmax) - t_in);
  return t_in;
}

bool RenderScene::intersect(const Ray& ray, const PrimRef& from, Hit* hit) const {
  const Vec3d o(ray.o), d(ray.d);
  int plane = -1;
  const double tp = nearest_plane(o, d, from, double(ray.tmax), &plane);
  // Embree only needs to look closer than the nearest plane.
  Ray er;
  const double t0 = embree_ray({ray.o, ray.d, plane >= 0 ? float(tp) : ray.tmax}, &er);
  RTCRayHit rh = make_rayhit(er, 0.0f, er.tmax, 0xFFFFFFFFu);
  if (RayLog* log = thread_ray_log()) {  // every ray, queried or not: the log counts the renderer's rays
    log->rays.push_back({rh.ray, from, from.kind == PrimRef::Kind::kNone ? LoggedRay::Kind::kCamera
                                                                         : LoggedRay::Kind::kSecondary});
  }
  if (t0 >= 0.0) {
    TraceContext ctx;
    rtcInitIntersectContext(&ctx.rtc);
    ctx.scene = this;
    ctx.from = from;
    rtcIntersect1(rtc_scene_.get(), &ctx.rtc, &rh);
  }
  const float t = t0 > 0.0 ? float(t0 + double(rh.ray.tfar)) : rh.ray.tfar;
  return finish_hit(o, d, plane, tp, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v, t, hit);
}

bool RenderScene::finish_hit(const Vec3d& o, const Vec3d& d, int plane, double tp, uint32_t g, uint32_t prim_id,
                             float hit_u, float hit_v, float tfar, Hit* hit) const {
  hit->smooth = false;  // set for triangles with vertex normals below
  if (g != RTC_INVALID_GEOMETRY_ID) {
    hit->t = tfar;
    for (int k = 0; k < 2; ++k) {
      if (g == triangles_[k].geom_id) {
        const TriangleBucket& b = triangles_[k];
        const uint32_t pid = prim_id;
        // Buckets store 3 unshared vertices per triangle (indices[3 pid + k] == 3 pid + k, for
        // Embree's own triangles): read them without the dependent load of the index.
        const Vec3f v0 = b.positions[3 * size_t(pid)], v1 = b.positions[3 * size_t(pid) + 1],
                    v2 = b.positions[3 * size_t(pid) + 2];
        const float u = hit_u, v = hit_v, w = 1.0f - u - v;
        // Interpolating the vertices (not o + t d) bounds the error by the vertices' magnitude.
        hit->p = v0 * w + v1 * u + v2 * v;
        hit->p_err = (abs(v0 * w) + abs(v1 * u) + abs(v2 * v)) * gamma_bound(7);
        hit->n = normalize(cross(v1 - v0, v2 - v0));
        hit->material = b.material_ids[pid];
        hit->prim = {PrimRef::Kind::kTriangle, pid, uint32_t(k)};
        hit->u = u;
        hit->v = v;
        if (!b.uvs.empty()) {
          const float* t = &b.uvs[6 * size_t(pid)];
          hit->tex_u = t[0] * w + t[2] * u + t[4] * v;
          hit->tex_v = t[1] * w + t[3] * u + t[5] * v;
        }
        hit->smooth = !b.normals.empty() && interpolate_shading_normal(&b.normals[9 * size_t(pid)], w, u, v, hit->n, &hit->ns);
        return true;
      }
      if (g == sphere_buckets_[k].geom_id) {
        const uint32_t index = sphere_buckets_[k].ids[prim_id];
        const Sphere& s = spheres_[index];
        // Recompute in double and project back onto the sphere (pbrt-v4's re-projection).
        const Vec3d pd = o + d * double(tfar);
        const Vec3d nd = normalize(pd - s.center);
        const Vec3d pr = s.center + nd * s.radius;
        hit->p = Vec3f(pr);
        hit->p_err = abs(hit->p) * gamma_bound(5) + Vec3f(float(4 * kDoubleEps * (max_component(abs(s.center)) + s.radius)));
        hit->n = Vec3f(nd);
        hit->material = s.material;
        hit->prim = {PrimRef::Kind::kSphere, index, uint32_t(k)};
        hit->u = hit->v = 0.0f;
        return true;
      }
    }
    return false;  // unreachable: every geometry is one of the buckets
  }
  if (plane < 0) return false;
  const Plane& pl = planes_[size_t(plane)];
  Vec3d pd = o + d * tp;
  pd = pd - pl.normal * dot(pd - pl.point, pl.normal);  // project onto the plane
  hit->t = float(tp);
  hit->p = Vec3f(pd);
  hit->p_err = abs(hit->p) * gamma_bound(3) + Vec3f(float(4 * kDoubleEps * max_component(abs(pl.point))));
  hit->n = Vec3f(pl.normal);
  hit->material = pl.material;
  hit->prim = {PrimRef::Kind::kPlane, uint32_t(plane), 0};
  hit->u = hit->v = 0.0f;
  return true;
}

bool RenderScene::opaque_plane_blocks(const Ray& ray, const PrimRef& from) const {
  const Vec3d o(ray.o), d(ray.d);
  for (size_t i = 0; i < planes_.size(); ++i) {
    if ((from.kind == PrimRef::Kind::kPlane && from.id == i) ||
        materials_[planes_[i].material].type == Material::Type::kGlass) {
      continue;
    }
    const double t = intersect_plane(o, d, planes_[i].point, planes_[i].normal);
    if (t > 0.0 && t < double(ray.tmax)) return true;
  }
  return false;
}

bool RenderScene::any_hit(const Ray& ray, const PrimRef& from) const {
  // The planes exactly as intersect() meets them; one whose point is beyond float range is no hit,
  // and Embree then looks only closer than it, as intersect() does.
  const Vec3d o(ray.o), d(ray.d);
  int plane = -1;
  const double tp = nearest_plane(o, d, from, double(ray.tmax), &plane);
  Hit h;
  if (plane >= 0 && finish_hit(o, d, plane, tp, RTC_INVALID_GEOMETRY_ID, 0, 0.0f, 0.0f, 0.0f, &h) && is_finite(h.p)) {
    return true;
  }
  Ray er;
  if (embree_ray({ray.o, ray.d, plane >= 0 ? float(tp) : ray.tmax}, &er) < 0.0) return false;
  TraceContext ctx;  // no glass list: glass blocks like any surface
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = this;
  ctx.from = from;
  RTCRay r = make_rayhit(er, 0.0f, er.tmax, kOpaqueMask | kGlassMask).ray;
  rtcOccluded1(rtc_scene_.get(), &ctx.rtc, &r);
  return r.tfar < 0.0f;
}

Rgb RenderScene::transmittance(const Ray& ray, const PrimRef& from) const {
  // Opaque planes first: cheapest.
  if (opaque_plane_blocks(ray, from)) return Rgb(0.0f);
  TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = this;
  ctx.from = from;
  GlassHits glass;
  // With glass in the scene, one traversal over both classes: opaque hits end it, glass
  // crossings are collected (sphere callback, triangle filter) and multiplied in order below.
  // This replaced an occlusion query plus a crossing-by-crossing glass walk (two or more
  // traversals for every unblocked shadow ray).
  if (has_glass_) ctx.glass = &glass;
  Ray er;
  const double t0 = embree_ray(ray, &er);
  RTCRay r = make_rayhit(er, 0.0f, er.tmax, has_glass_ ? kOpaqueMask | kGlassMask : kOpaqueMask).ray;
  if (RayLog* log = thread_ray_log()) log->rays.push_back({r, from, LoggedRay::Kind::kShadow});
  if (t0 >= 0.0) {
    rtcOccluded1(rtc_scene_.get(), &ctx.rtc, &r);
    if (r.tfar < 0.0f) return Rgb(0.0f);
  }
  if (!has_glass_) return Rgb(1.0f);
  ctx.glass = nullptr;
  return glass_product(ray, &ctx, &glass);
}

Rgb RenderScene::glass_product(const Ray& ray, TraceContext* ctx, GlassHits* glass_hits) const {
  const Vec3d o(ray.o), d(ray.d);
  const PrimRef& from = ctx->from;
  GlassHits& glass = *glass_hits;
  // Glass between the point and the light: multiply the crossings in order along the ray, so the
  // product is formed in the same order every time (bit-identical results).
  Rgb T(1.0f);
  for (size_t i = 0; i < planes_.size(); ++i) {
    if ((from.kind == PrimRef::Kind::kPlane && from.id == i) ||
        materials_[planes_[i].material].type != Material::Type::kGlass) {
      continue;
    }
    const double t = intersect_plane(o, d, planes_[i].point, planes_[i].normal);
    if (t > 0.0 && t < double(ray.tmax)) T *= materials_[planes_[i].material].transmittance;
  }
  if (glass.overflow) return glass_transmittance_walk(ray, ctx, T);
  // Embree reports candidates in traversal order: sort by t (ties by material, so the order is
  // total), and count crossings at the same t once, as the walk stepping past each t did.
  std::sort(glass.hits, glass.hits + glass.count, [](const GlassHit& a, const GlassHit& b) {
    return a.t < b.t || (a.t == b.t && a.material < b.material);
  });
  for (int i = 0; i < glass.count; ++i) {
    if (i > 0 && glass.hits[i].t == glass.hits[i - 1].t) continue;
    T *= materials_[glass.hits[i].material].transmittance;
    if (!(T.x > 0 || T.y > 0 || T.z > 0)) break;
  }
  return T;
}

// The crossing-by-crossing walk, kept for rays that cross more than kMaxGlassHits glass surfaces.
Rgb RenderScene::glass_transmittance_walk(const Ray& original, TraceContext* ctx, Rgb T) const {
  Ray ray;
  if (embree_ray(original, &ray) < 0.0) return T;
  float tnear = 0.0f;
  for (int crossing = 0; crossing < kMaxGlassCrossings; ++crossing) {
    RTCRayHit rh = make_rayhit(ray, tnear, ray.tmax, kGlassMask);
    if (RayLog* log = thread_ray_log()) log->rays.push_back({rh.ray, ctx->from, LoggedRay::Kind::kGlassWalk});
    rtcIntersect1(rtc_scene_.get(), &ctx->rtc, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
    uint32_t m = 0;
    if (rh.hit.geomID == triangles_[1].geom_id) m = triangles_[1].material_ids[rh.hit.primID];
    else m = spheres_[sphere_buckets_[1].ids[rh.hit.primID]].material;
    T *= materials_[m].transmittance;
    if (!(T.x > 0 || T.y > 0 || T.z > 0)) break;
    tnear = std::nextafter(rh.ray.tfar, std::numeric_limits<float>::infinity());
  }
  return T;
}

Rgb RenderScene::textured_albedo(const Hit& hit, const Material& m) const {
  const auto& t = m.uv_transform;
  const double u = t[0] * hit.tex_u + t[1] * hit.tex_v + t[2], v = t[3] * hit.tex_u + t[4] * hit.tex_v + t[5];
  return m.albedo * sample_texture(textures_[size_t(m.albedo_texture)], u, v);
}

int RenderScene::checker_parity(const Hit& hit, const Material& m) const {
  const double s = m.checker_scale;
  if (hit.prim.kind == PrimRef::Kind::kPlane) {
    // 2D squares in the plane's own basis, anchored at its point: independent of where the
    // plane is in the world.
    const Plane& pl = planes_[hit.prim.id];
    const Vec3d rel = Vec3d(hit.p) - pl.point;
    const double a = std::floor(dot(rel, Vec3d(pl.b1)) / s), b = std::floor(dot(rel, Vec3d(pl.b2)) / s);
    return int(int64_t(a + b) & 1);
  }
  const Vec3d w = Vec3d(hit.p) + origin_;  // solid 3D checker in world space
  const double sum = std::floor(w.x / s) + std::floor(w.y / s) + std::floor(w.z / s);
  return int(int64_t(sum) & 1);
}

}  // namespace tessera

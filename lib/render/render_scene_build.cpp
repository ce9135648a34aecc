// SPDX-License-Identifier: Apache-2.0
// Building a RenderScene's data from a Scene at one frame: render space (the eye at the origin),
// the lights, the spheres, planes and triangle buckets, the tables the SIMD batch reads and the
// radii the Embree boxes and far rays depend on. The Embree scene over that data is built last
// (render_scene_embree.cpp).
#include <algorithm>
#include <cmath>
#include <map>

#include "math/transform.h"
#include "render/render_scene_internal.h"
#include "render/shading_normal.h"
#include "scene/animation.h"

namespace tessera {

namespace {

Transform object_transform(const TransformDesc& t) {
  if (t.matrix) return Transform::affine(*t.matrix);
  return Transform::translate(t.translate) * Transform::rotate_xyz_deg(t.rotate_deg) * Transform::scale(t.scale);
}

bool is_glass(const Material& m) { return m.type == Material::Type::kGlass; }

}  // namespace

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
  camera_ = {Vec3f(sp.p0 - origin_), Vec3f(sp.p1 - sp.p0), Vec3f(sp.p2 - sp.p0)};
  add_lights(scene.lights);
  add_objects(scene, state);
  finish_tables();
  measure_bounds();
  make_scan();
  build_embree_scene();
}

void RenderScene::make_scan() {
  scan_spheres_ = options_.spheres == SphereSearch::kScanSmall && triangles_[0].material_ids.empty() &&
                  triangles_[1].material_ids.empty() && spheres_.size() <= kScanSpheres;
  if (!scan_spheres_) return;
  // Each sphere's place in its bucket, read off the buckets add_objects() made.
  scan_.resize(spheres_.size());
  for (uint32_t b = 0; b < 2; ++b) {
    const std::vector<uint32_t>& ids = sphere_buckets_[b].ids;
    for (uint32_t k = 0; k < ids.size(); ++k) scan_[ids[k]] = {b, k};
  }
  for (const Sphere& s : spheres_) {
    // The scan takes rays that start near (starts_near(): |o|max <= near_bound(), so |o|_1 is at
    // most three times that).
    add_scan_sphere(&scan_table_, s.center.x, s.center.y, s.center.z, s.radius, 3.0 * double(near_bound()));
  }
}

void RenderScene::add_lights(const std::vector<Light>& lights) {
  for (const Light& l : lights) {
    if (l.type == Light::Type::kPoint) {
      point_lights_.push_back({Vec3f(l.position - origin_), l.intensity});
    } else if (l.type == Light::Type::kSpot) {
      // KHR_lights_punctual's falloff: s = clamp(cos_angle * scale + offset, 0, 1), squared,
      // with scale = 1 / max(0.001, cos(inner) - cos(outer)), offset = -cos(outer) * scale:
      // 1 inside the inner cone, 0 outside the outer one.
      const double cos_outer = std::cos(l.outer_cone_rad), cos_inner = std::cos(l.inner_cone_rad);
      const double scale = 1.0 / std::max(0.001, cos_inner - cos_outer);
      spot_lights_.push_back({Vec3f(l.position - origin_), l.intensity, Vec3f(normalize(l.direction)), float(scale),
                              float(-cos_outer * scale)});
    } else {
      directional_lights_.push_back({Vec3f(normalize(l.direction)), l.irradiance});
    }
  }
}

void RenderScene::add_objects(const Scene& scene, const FrameState& state) {
  for (size_t oi = 0; oi < scene.objects.size(); ++oi) {
    const SceneObject& obj = scene.objects[oi];
    const Transform xf = object_transform(state.transforms[oi]);
    switch (obj.type) {
      case SceneObject::Type::kSphere: {
        const uint32_t m = uint32_t(obj.material);
        const uint32_t index = uint32_t(spheres_.size());
        spheres_.push_back(
            {xf.point(obj.center) - origin_, obj.radius * std::abs(state.transforms[oi].scale.x), m, uint32_t(oi)});
        sphere_buckets_[is_glass(materials_[m]) ? 1 : 0].ids.push_back(index);
        break;
      }
      case SceneObject::Type::kPlane: {
        Plane p;
        p.point = xf.point(obj.point) - origin_;
        p.normal = normalize(xf.normal(obj.normal));
        Vec3f b1, b2;
        orthonormal_basis(Vec3f(p.normal), b1, b2);
        p.b1 = Vec3d(b1), p.b2 = Vec3d(b2);
        p.material = uint32_t(obj.material);
        p.object = uint32_t(oi);
        planes_.push_back(p);
        break;
      }
      case SceneObject::Type::kMesh: add_mesh(scene.meshes[size_t(obj.mesh)], uint32_t(oi), xf); break;
    }
  }
}

// A mesh's triangles go to the bucket of their material's class, with their own three vertices;
// emissive ones also make an area light per material.
void RenderScene::add_mesh(const Mesh& mesh, uint32_t object, const Transform& xf) {
  const bool flip = xf.determinant() < 0;  // mirroring reverses winding: undo it
  std::vector<Vec3f> world(mesh.positions.size());
  for (size_t v = 0; v < mesh.positions.size(); ++v) world[v] = Vec3f(xf.point(Vec3d(mesh.positions[v])) - origin_);
  std::map<uint32_t, size_t> light_of_material;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const uint32_t m = mesh.material_ids[t];
    uint32_t i0 = mesh.indices[3 * t], i1 = mesh.indices[3 * t + 1], i2 = mesh.indices[3 * t + 2];
    if (flip) std::swap(i1, i2);
    const Vec3f a = world[i0], b = world[i1], c = world[i2];
    if (!(length(cross(b - a, c - a)) > 0)) continue;  // collapsed by float rounding or scale
    TriangleBucket& bucket = triangles_[is_glass(materials_[m]) ? 1 : 0];
    const uint32_t base = uint32_t(bucket.positions.size());
    // Unshared vertices keep buckets simple; meshes here are small next to their BVH.
    bucket.positions.insert(bucket.positions.end(), {a, b, c});
    bucket.indices.insert(bucket.indices.end(), {base, base + 1, base + 2});
    bucket.material_ids.push_back(m);
    bucket.sources.push_back({object, uint32_t(t)});
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
}

// What is complete only once every object is in: per-triangle tables padded to every triangle,
// area-light CDFs normalized, the planes' SIMD table, whether any glass is in the scene.
void RenderScene::finish_tables() {
  make_error_terms();
  for (const Material& m : materials_) checker_inverse_.push_back(checker_inverse(m.checker_scale));
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
  for (const Plane& p : planes_) glass_planes_ = glass_planes_ || is_glass(materials_[p.material]);
  opaque_index_.assign(planes_.size(), -1);
  for (size_t i = 0; i < planes_.size(); ++i) {
    if (is_glass(materials_[planes_[i].material])) continue;
    opaque_index_[i] = int32_t(opaque_planes_.size());
    opaque_planes_.push_back(uint32_t(i));
    opaque_plane_table_.insert(opaque_plane_table_.end(), plane_table_.begin() + 6 * long(i),
                               plane_table_.begin() + 6 * long(i + 1));
    opaque_plane_ids_.insert(opaque_plane_ids_.end(), {planes_[i].material, planes_[i].object});
  }
  has_glass_ = has_glass_ || glass_planes_;
}

void RenderScene::measure_bounds() {
  for (const TriangleBucket& b : triangles_) {
    for (const Vec3f& p : b.positions) triangle_radius_ = std::max(triangle_radius_, max_component(abs(p)));
    bounds_radius_ = triangle_radius_;
  }
  for (const Sphere& sp : spheres_) {
    bounds_radius_ = std::max(bounds_radius_, float(max_component(abs(sp.center)) + sp.radius));
  }
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// One frame of a Scene, ready to trace: camera-relative float geometry in an Embree scene
// (triangles + analytic spheres as user geometry), infinite planes beside it, lights and
// materials. Immutable after construction, so any number of threads may trace it at once.
//
// lib/render's own header: the integrator, the tile renderer and the scene's own files read the
// whole class, its packet and ISA-cloned variants included. Everyone else (the worker, the ray
// server and lib/rays, the CLI) sees a RenderScene through render/render_scene.h: built by
// make_render_scene(), passed whole to the renderer, asked its few queries there. This header
// includes no Embree header either: the Embree side (the intersect context our callbacks read,
// their per-geometry data, the glass crossings a shadow ray collects) is declared here by name
// only and defined in render/render_scene_embree.h.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "render/hit.h"
#include "render/isa_clones.h"
#include "render/ray.h"
#include "render/render_options.h"
#include "render/render_scene.h"
#include "render/sphere_scan.h"
#include "render/triangle_cluster.h"
#include "scene/scene.h"

// Embree's scene object (RTCScene is a pointer to it): named, not defined, so that holding the
// scene here needs no Embree header, and a query still reads the pointer straight from the
// RenderScene.
struct RTCSceneTy;

namespace tessera {

struct RayBatch;
struct RayLanes;
struct RayArrays;
struct HitBatch;
struct FrameState;
class Transform;

class RenderScene {
 public:
  RenderScene(const Scene& scene, int frame, RenderOptions options = {});
  ~RenderScene();
  RenderScene(const RenderScene&) = delete;
  RenderScene& operator=(const RenderScene&) = delete;

  // Nearest hit along the ray in (0, ray.tmax]; `from` is the primitive the ray leaves.
  bool intersect(const Ray& ray, const PrimRef& from, Hit* hit) const;
  // intersect(ray i, PrimRef{}) for n <= kRayBatch rays given as arrays of components
  // (render/ray_batch.h), one Embree query per ray (so an answer never depends on the batch),
  // with the common hits' arithmetic in SIMD across rays (render_scene_batch.cpp): bit for bit
  // intersect()'s answers. For queries from no surface: the ray service's.
  void intersect_batch(const RayBatch& rays, size_t n, HitBatch* hits) const;
  // intersect() for n <= kPacket rays at once, traced as one Embree packet (render_scene_packet.cpp).
  // A lane's result depends only on its own ray, except that exact ties between two primitives
  // at the same t may resolve by the packet's traversal order: callers must form packets as a
  // pure function of the pixel (the tile renderer packs one pixel's consecutive samples).
  // The rays come as arrays of components (render/ray_lanes.h), as the integrator holds them.
  static constexpr int kPacket = 8;
  TESSERA_ISA_CLONES void intersect_packet(const RayLanes& rays, const PrimRef* from, int n, Hit* hits,
                                           bool* found) const;
  // The same for rays given a struct each (tests, the ray service's checks): packed into lanes.
  void intersect_packet(const Ray* rays, const PrimRef* from, int n, Hit* hits, bool* found) const;
  // Whether intersect() would find a hit with a finite point, by an any-hit traversal
  // (rtcOccluded1) that stops at the first surface met, glass included: line-of-sight queries of
  // the ray service (lib/rays).
  bool any_hit(const Ray& ray, const PrimRef& from) const;
  // any_hit(ray i, PrimRef{}) for n <= kRayBatch rays as arrays of components, the planes in SIMD
  // (render_scene_batch.cpp): blocked[i] = 1 or 0, bit for bit any_hit()'s; lanes with skip set
  // are left as they are.
  void any_hit_batch(const RayBatch& rays, size_t n, uint8_t* blocked) const;
  // transmittance() for n <= kPacket rays at once, one Embree packet (render_scene_packet.cpp);
  // the Ray overload packs them into lanes.
  TESSERA_ISA_CLONES void transmittance_packet(const RayLanes& rays, const PrimRef* from, int n, Rgb* T) const;
  void transmittance_packet(const Ray* rays, const PrimRef* from, int n, Rgb* T) const;
  // Fraction of light arriving along the ray over (0, ray.tmax]: 0 if an opaque surface blocks
  // it, else the product of the transmittances of the glass surfaces crossed (unrefracted).
  Rgb transmittance(const Ray& ray, const PrimRef& from) const;

  struct AreaLight {
    std::vector<Vec3f> v;        // 3 vertices per triangle, render space
    std::vector<float> cdf;      // cumulative area, normalized to 1
    float area = 0;              // total area
    Rgb emission;
  };
  struct PointLight { Vec3f position; Rgb intensity; };
  struct DirectionalLight { Vec3f direction; Rgb irradiance; };  // direction the light travels
  // A point light whose intensity falls off with the angle to its axis (see add_lights()).
  struct SpotLight {
    Vec3f position;
    Rgb intensity;
    Vec3f direction;  // the axis, the way the light travels
    float cone_scale, cone_offset;
    float falloff(const Vec3f& w_from_light) const {
      const float s = std::clamp(dot(direction, w_from_light) * cone_scale + cone_offset, 0.0f, 1.0f);
      return s * s;
    }
  };

  // Render-space camera: the eye is the origin; pixel point = p0 + u du + v dv.
  struct Camera { Vec3f p0, du, dv; };

  const Camera& camera() const { return camera_; }
  const ImageSettings& image() const { return image_; }
  int frame() const { return frame_; }
  const Rgb& background() const { return background_; }
  const Material& material(uint32_t id) const { return materials_[id]; }
  const std::vector<PointLight>& point_lights() const { return point_lights_; }
  const std::vector<DirectionalLight>& directional_lights() const { return directional_lights_; }
  const std::vector<SpotLight>& spot_lights() const { return spot_lights_; }
  const std::vector<AreaLight>& area_lights() const { return area_lights_; }
  // A textured diffuse material's albedo at a hit: albedo x the texture at the hit's uv.
  Rgb textured_albedo(const Hit& hit, const Material& m) const;
  // Checker parity (0 or 1) of a diffuse checker material at a hit. Inline: the shading of every
  // checker hit calls it (4 % of a Whitted frame by perf).
  int checker_parity(const Hit& hit, const Material& m) const {
    // x / scale, by the reciprocal made at build time where that gives the same bits.
    const double inv = checker_inverse_[hit.material], scale = m.checker_scale;
    const auto of = [inv, scale](double x) { return inv != 0 ? x * inv : x / scale; };
    if (hit.prim.kind == PrimRef::Kind::kPlane) {
      // 2D squares in the plane's own basis, anchored at its point: independent of where the
      // plane is in the world.
      const Plane& pl = planes_[hit.prim.id];
      const Vec3d rel = Vec3d(hit.p) - pl.point;
      const double a = std::floor(of(dot(rel, pl.b1))), b = std::floor(of(dot(rel, pl.b2)));
      return int(int64_t(a + b) & 1);
    }
    const Vec3d w = Vec3d(hit.p) + origin_;  // solid 3D checker in world space
    const double sum = std::floor(of(w.x)) + std::floor(of(w.y)) + std::floor(of(w.z));
    return int(int64_t(sum) & 1);
  }
  Vec3d origin() const { return origin_; }  // world position of render space's origin (the eye)
  size_t triangle_count() const;
  size_t sphere_count() const { return spheres_.size(); }
  // Where a primitive came from (render/render_scene.h). Read by the ray service.
  using Source = PrimSource;
  Source source_of(const PrimRef& prim) const;
  // Max |coordinate| of all bounded geometry (triangles, spheres), render space: the ray service
  // moves far ray origins to this cube's neighbourhood in double before rounding them to float.
  float bounds_radius() const { return bounds_radius_; }

  // Its layout is read in place by the batch's SIMD finish (render/ray_batch_simd.h).
  struct Sphere { Vec3d center; double radius; uint32_t material; uint32_t object; };
  const std::vector<Sphere>& spheres() const { return spheres_; }
  // Whether packets of rays scan the spheres rather than traverse Embree's BVH (SphereSearch).
  bool scans_spheres() const { return scan_spheres_; }
  // Half-width added to every user-geometry bounding box (see set_padded_bounds() in
  // user_geometry.cpp): a bound on the rounding error of Embree's box test for rays starting
  // within 32x the radius of the scene's triangles around the eye. Triangles only: one huge
  // sphere (a 1e6 ground) would otherwise widen every triangle's box by ~R/2^16 and defeat the
  // BVH (measured: 1000x slower); spheres need no such guarantee (a box-test error there is a
  // tangent ray).
  float box_padding(float box_magnitude) const { return 0x1p-16f * (box_magnitude + triangle_radius_); }

  // The Embree side, defined in render/render_scene_embree.h: the intersect context our
  // callbacks read, the glass crossings a shadow ray collects, and the callbacks' data per
  // geometry.
  struct TraceContext;
  struct GlassHit;
  struct GlassHits;
  struct TriangleGeomData;
  struct SphereGeomData;
  // The Embree scene (benchmarks replay the renderer's rays on it; see render/ray_log.h).
  RTCSceneTy* embree_scene() const { return rtc_scene_.get(); }
  // Embree geometry masks of the two material classes.
  static constexpr uint32_t kOpaqueMask = 1, kGlassMask = 2;

 private:
  // b1, b2: the plane's own basis (its checker's axes), float values held in double, as the
  // checker reads them.
  struct Plane { Vec3d point; Vec3d normal; Vec3d b1, b2; uint32_t material; uint32_t object; };
  // The geometry id of a bucket not in the Embree scene: Embree's RTC_INVALID_GEOMETRY_ID
  // (render_scene_embree.h checks that they agree).
  static constexpr uint32_t kNoGeometry = UINT32_MAX;
  // The triangles and spheres of one material class ([0] opaque, [1] glass), each one Embree
  // geometry. Held by value, not behind a pointer: finish_hit() and the batch read them on every
  // hit.
  struct TriangleBucket {
    std::vector<Vec3f> positions;      // +1 padding element: Embree reads 16 bytes per vertex
    std::vector<uint32_t> indices;
    std::vector<uint32_t> material_ids;
    std::vector<Source> sources;       // per triangle
    std::vector<float> uvs;  // 6 per triangle (its vertices' uv) when any triangle is textured; else empty
    std::vector<float> normals;  // 9 per triangle (unit vertex normals, 0: flat) when any has them; else empty
    std::vector<TriangleCluster> clusters;  // the watertight test's Embree primitives (triangle_cluster.h)
    uint32_t geom_id = kNoGeometry;
  };
  struct SphereBucket {
    std::vector<uint32_t> ids;  // indices into spheres_
    uint32_t geom_id = kNoGeometry;
    uint32_t mask = 0;
  };
  // What Embree's user-geometry callbacks are given, per geometry (render_scene_embree.h). They
  // reach it through Embree's geometry user pointer, never through this one, so holding it
  // apart costs a query nothing.
  struct UserGeometryData;
  // Releases the Embree scene (rtcReleaseScene, in render_scene_embree.cpp).
  struct ReleaseEmbreeScene {
    void operator()(RTCSceneTy* scene) const;
  };

  // The steps of construction (render_scene_build.cpp), in order.
  void build(const Scene& scene, int frame);
  void add_lights(const std::vector<Light>& lights);
  void add_objects(const Scene& scene, const FrameState& state);
  void add_mesh(const Mesh& mesh, uint32_t object, const Transform& xf);
  void finish_tables();
  void measure_bounds();
  void build_embree_scene();  // render_scene_embree.cpp

  double nearest_plane(const Vec3d& o, const Vec3d& d, const PrimRef& from, double tmax, int* which) const;
  // The ray as Embree gets it. Embree's box test errs in proportion to the origin's magnitude,
  // and box_padding() covers origins within 16 R_tri (max norm) of the eye; a ray starting
  // beyond 16 R (R = bounds_radius_: all bounded geometry; only a ray leaving an infinite plane
  // or a huge sphere can) starts instead where it enters the cube |x| <= 2 R, which holds all
  // bounded geometry. (Between 16 R_tri and 16 R, with a sphere far bigger than the meshes,
  // is the gap docs/accuracy.md describes.) Returns the distance skipped (0 for every
  // other ray) and sets *embree_ray (tmax shortened to match), or -1 when the ray never enters
  // the cube before tmax, so no bounded geometry can be met.
  double embree_ray(const Ray& ray, Ray* embree_ray) const {
    *embree_ray = ray;  // the common case, inline: every ray but those from far plane points
    return starts_near(ray.o) ? 0.0 : embree_ray_from_far(ray, embree_ray);
  }
  // Whether Embree can take a ray from o as it is (embree_ray()): within 16 R, max norm. The one
  // bound lanes_start_near() and the sphere scan's margin (make_scan()) are read against too.
  float near_bound() const { return 16.0f * bounds_radius_; }
  bool starts_near(const Vec3f& o) const { return max_component(abs(o)) <= near_bound(); }
  // Whether the rays of lanes 0..n-1 all start near: Embree (and the sphere scan) take them as they are.
  TESSERA_ISA_CLONES bool lanes_start_near(const RayArrays& rays, int n) const;
  double embree_ray_from_far(const Ray& ray, Ray* embree_ray) const;
  Rgb glass_transmittance_walk(const Ray& ray, TraceContext* ctx, Rgb T) const;
  // The halves of intersect() and transmittance() around the Embree query, shared with the
  // packet versions (render_scene_packet.cpp).
  TESSERA_ISA_CLONES bool finish_hit(const Vec3d& o, const Vec3d& d, int plane, double tp, uint32_t geom_id,
                                     uint32_t prim_id, float u, float v, float tfar, Hit* hit) const;
  // The rest of finish_hit()'s answer on a sphere or a plane, given its point p (stored here too)
  // and normal: the point's error bound, the material and the primitive. Shared with the packet's
  // SIMD finish. Inline, and p passed in: read back from the Hit just written, p cost a
  // store-forwarding stall per hit (a 64-bit load of two 32-bit stores; 3 % of a Whitted frame
  // by perf).
  void finish_sphere_hit(uint32_t index, uint32_t bucket, const Vec3f& p, Hit* hit) const {
    hit->p = p;
    // sphere_err_[index]: float(4 kDoubleEps (max |centre| + radius)), the centre's and radius's share.
    hit->p_err = abs(p) * gamma_bound(5) + Vec3f(sphere_err_[index]);
    hit->material = spheres_[index].material;
    hit->prim = {PrimRef::Kind::kSphere, index, bucket};
    hit->u = hit->v = 0.0f;
  }
  void finish_plane_hit(int plane, const Vec3f& p, Hit* hit) const {
    hit->p = p;
    hit->p_err = abs(p) * gamma_bound(3) + Vec3f(plane_err_[size_t(plane)]);  // float(4 kDoubleEps max |point|)
    hit->material = planes_[size_t(plane)].material;
    hit->prim = {PrimRef::Kind::kPlane, uint32_t(plane), 0};
    hit->u = hit->v = 0.0f;
  }
  bool opaque_plane_blocks(const Ray& ray, const PrimRef& from) const;
  // A scene of at most kScanSpheres spheres and no triangles is scanned, not traversed: a whole
  // packet's rays are tested against each sphere in turn (render_scene_scan.cpp), where Embree
  // would run its BVH and call back. scan_[s]: sphere s's bucket and its index there (the
  // primitive id Embree would report).
  struct ScanSphere { uint32_t bucket, prim; };
  bool scan_spheres_ = false;
  std::vector<ScanSphere> scan_;
  ScanTable scan_table_;
  void make_scan();
  // rtcIntersect8 on a packet of rays that start near, as a scan: for each lane in the mask
  // `lanes`, tfar[i] shortened to its nearest sphere hit in (0, tfar[i]), and geom[i], prim[i]
  // set to it, as the sphere callback writes them; lanes without one are left alone.
  TESSERA_ISA_CLONES void scan_intersect(const RayArrays& rays, const PrimRef* from, uint32_t lanes, float* tfar,
                                         uint32_t* geom, uint32_t* prim) const;
  // sphere_roots() of sphere s for the lanes in the mask `lanes` (others: -1), within (0, tfar[i]),
  // each lane leaving the sphere or not as from[i] says: the scan's one exact test.
  TESSERA_ISA_CLONES void scan_roots(const RayArrays& rays, const PrimRef* from, uint32_t lanes, size_t s,
                                     const float* tfar, double* t) const;
  // rtcOccluded8 likewise: tfar[i] = -inf for a valid lane an opaque sphere blocks in
  // (0, tfar[i]); glass crossings collected into glass[i], as the callback collects them.
  TESSERA_ISA_CLONES void scan_occluded(const RayArrays& rays, const PrimRef* from, const int* valid, float* tfar,
                                        GlassHits* glass) const;
  Rgb glass_product(const Ray& ray, TraceContext* ctx, GlassHits* glass) const;

  ImageSettings image_;
  int frame_ = 0;
  Vec3d origin_;
  Camera camera_;
  Rgb background_;
  RenderOptions options_;
  std::vector<Material> materials_;
  // Per material: 1 / checker_scale where the scale is a power of two (the checker's coordinate
  // is then a multiplication, the division's bits), else 0 (render_scene_texture.cpp).
  std::vector<double> checker_inverse_;
  static double checker_inverse(double scale);
  std::vector<Texture> textures_;
  std::vector<PointLight> point_lights_;
  std::vector<DirectionalLight> directional_lights_;
  std::vector<SpotLight> spot_lights_;
  std::vector<AreaLight> area_lights_;
  std::vector<Sphere> spheres_;
  std::vector<Plane> planes_;
  // planes_ for SIMD (ray_batch_simd.h): 6 doubles each (point, normal), 2 indices (material, object).
  std::vector<double> plane_table_;
  std::vector<uint32_t> plane_ids_;
  TriangleBucket triangles_[2];  // [0] opaque, [1] glass
  SphereBucket sphere_buckets_[2];
  bool has_glass_ = false;
  bool glass_planes_ = false;  // some plane is glass (glass_product walks the planes)
  // The indices of the opaque planes, ascending: the ones a shadow ray tests (opaque_plane_blocks),
  // without a material lookup per plane and ray.
  std::vector<uint32_t> opaque_planes_;
  // The constant term of a hit point's error bound, per sphere and per plane (finish_sphere_hit,
  // finish_plane_hit): made once, not per hit.
  std::vector<float> sphere_err_, plane_err_;
  void make_error_terms();
  // The same planes as a table for SIMD (plane_table_'s layout), and each plane's index in it
  // (-1: glass): a packet's shadow rays test them all at once (transmittance_packet).
  std::vector<double> opaque_plane_table_;
  std::vector<uint32_t> opaque_plane_ids_;
  std::vector<int32_t> opaque_index_;
  // Whether a shadow ray whose Embree query collected `hits` can have crossed glass: if not,
  // its transmittance is 1 without glass_product's walk.
  bool may_cross_glass(const GlassHits& hits) const;
  std::unique_ptr<UserGeometryData> user_geometry_;
  float bounds_radius_ = 0;    // max |coordinate| of bounded geometry (triangles, spheres), render space
  float triangle_radius_ = 0;  // max |coordinate| of triangle vertices, render space
  std::unique_ptr<RTCSceneTy, ReleaseEmbreeScene> rtc_scene_;
};

}  // namespace tessera

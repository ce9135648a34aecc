// SPDX-License-Identifier: Apache-2.0
// RayTracer against analytic answers: spheres, planes, a closed mesh (rays through its shared
// edges and vertices), grazing and parallel rays, t_min/t_max, far origins; and against the
// renderer itself: the camera rays of showcase frames hit bit for bit what the renderer's
// primary rays hit.
#include "rays/ray_tracer.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "render/ray_log.h"
#include "render/render_scene_internal.h"
#include "rays/ray_check.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"

namespace tessera::rays {
namespace {

namespace fs = std::filesystem;

// A closed octahedron |x| + |y| + |z| = 1, outward CCW winding: from its centre, a ray along
// unit d meets it at t = 1 / |d|_1, on the face with normal sign(d) / sqrt(3). Its 12 edges and
// 6 vertices are shared between faces.
void write_octahedron(const fs::path& path) {
  std::ofstream obj(path);
  obj << "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n";
  for (int sx : {1, -1}) {
    for (int sy : {1, -1}) {
      for (int sz : {1, -1}) {
        const int X = sx > 0 ? 1 : 2, Y = sy > 0 ? 3 : 4, Z = sz > 0 ? 5 : 6;
        // Flipping one axis reverses the orientation: swap two vertices to stay outward.
        if (sx * sy * sz > 0) obj << "f " << X << ' ' << Y << ' ' << Z << "\n";
        else obj << "f " << X << ' ' << Z << ' ' << Y << "\n";
      }
    }
  }
}

class RayTracerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_rays_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    write_octahedron(dir_ / "octa.obj");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A scene of `objects` seen from `eye` (render space is world minus the eye).
  RayTracer tracer(const std::string& objects, const std::string& eye = "[0, 3, 20]", int frame = 0,
                   const std::string& animation = "") {
    const std::string json = R"({"camera": {"position": )" + eye + R"(, "look_at": [0, 0, 0]},
      "materials": {"d": {"type": "diffuse"}, "g": {"type": "glass"}}, "objects": [)" + objects + "]" +
                             (animation.empty() ? "" : ", \"animation\": " + animation) + "}";
    std::ofstream(dir_ / "s.json") << json;
    auto scene = std::make_shared<const Scene>(load_scene((dir_ / "s.json").string()));
    return RayTracer(scene, make_render_scene(*scene, frame));
  }

  WorldHit nearest(const RayTracer& t, const Vec3d& o, const Vec3d& d, float tmin = 0.0f,
                   float tmax = INFINITY) {
    WorldRay r{o, normalize(d), tmin, tmax};
    WorldHit h;
    t.nearest(&r, 1, &h);
    // Every analytic case here (edges, vertices, grazing, interval ends, far origins) also
    // checks the occlusion query's own any-hit traversal against the nearest hit.
    WorldHit occ;
    t.occluded(&r, 1, &occ);
    EXPECT_EQ(occ.hit, h.hit) << "occlusion disagrees with the nearest hit";
    return h;
  }

  fs::path dir_;
};

void expect_vec(const Vec3d& got, const Vec3d& want, double tol) {
  EXPECT_NEAR(got.x, want.x, tol);
  EXPECT_NEAR(got.y, want.y, tol);
  EXPECT_NEAR(got.z, want.z, tol);
}

constexpr const char* kSphere = R"({"type": "sphere", "name": "ball", "center": [0, 0, 10], "radius": 2, "material": "d"})";
constexpr const char* kFloor = R"({"type": "plane", "name": "floor", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "g"})";
constexpr const char* kOcta = R"({"type": "mesh", "name": "octa", "file": "octa.obj", "material": "d"})";

TEST_F(RayTracerTest, SphereHitsFromOutsideAndInsideMatchTheAnalyticRoots) {
  const RayTracer t = tracer(kSphere);
  WorldHit h = nearest(t, {0, 0, 0}, {0, 0, 1});
  ASSERT_TRUE(h.hit);
  EXPECT_FLOAT_EQ(h.t, 8.0f);
  expect_vec(h.p, {0, 0, 8}, 1e-6);
  expect_vec(Vec3d(h.n), {0, 0, -1}, 1e-6);   // outward
  expect_vec(Vec3d(h.ns), {0, 0, -1}, 1e-6);  // facing the ray
  EXPECT_EQ(t.scene().objects[h.object].name, "ball");
  EXPECT_EQ(h.primitive, 0u);
  EXPECT_EQ(t.scene().materials[h.material].name, "d");
  // An oblique ray: |o + t d - c| = r, solved in closed form.
  const Vec3d d = normalize(Vec3d(0.1, 0.1, 1));
  const Vec3d o(0, 0, 0), c(0, 0, 10);
  const double b = dot(d, o - c), disc = b * b - (dot(o - c, o - c) - 4.0);
  const double t0 = -b - std::sqrt(disc);
  h = nearest(t, o, d);
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.t, t0, 1e-5);
  expect_vec(Vec3d(h.n), normalize(o + d * t0 - c), 1e-6);
  // From the centre: the far wall at r, the normal still outward, the shading normal facing back.
  h = nearest(t, {0, 0, 10}, {0, 1, 0});
  ASSERT_TRUE(h.hit);
  EXPECT_FLOAT_EQ(h.t, 2.0f);
  expect_vec(Vec3d(h.n), {0, 1, 0}, 1e-6);
  expect_vec(Vec3d(h.ns), {0, -1, 0}, 1e-6);
  EXPECT_FALSE(nearest(t, {0, 0, 0}, {0, 0, -1}).hit);
}

TEST_F(RayTracerTest, PlaneHitsAtTheAnalyticDistanceAndParallelRaysMiss) {
  const RayTracer t = tracer(kFloor);
  WorldHit h = nearest(t, {3, 5, -2}, {0, -1, 0});
  ASSERT_TRUE(h.hit);
  EXPECT_FLOAT_EQ(h.t, 6.0f);
  expect_vec(h.p, {3, -1, -2}, 1e-6);
  expect_vec(Vec3d(h.n), {0, 1, 0}, 0);
  EXPECT_EQ(t.scene().objects[h.object].name, "floor");
  h = nearest(t, {0, 5, 0}, {1, -1, 0});  // 45 degrees: t = 6 sqrt(2)
  ASSERT_TRUE(h.hit);
  EXPECT_NEAR(h.t, 6.0 * std::sqrt(2.0), 1e-5);
  expect_vec(h.p, {6, -1, 0}, 1e-5);
  // From below, the two-sided plane is met too; its shading normal faces the ray.
  h = nearest(t, {0, -4, 0}, {0, 1, 0});
  ASSERT_TRUE(h.hit);
  EXPECT_FLOAT_EQ(h.t, 3.0f);
  expect_vec(Vec3d(h.ns), {0, -1, 0}, 0);
  // Parallel above the plane, and parallel inside it: misses, no NaN.
  EXPECT_FALSE(nearest(t, {0, 5, 0}, {1, 0, 0}).hit);
  h = nearest(t, {0, -1, 0}, {1, 0, 1});
  EXPECT_FALSE(h.hit);
  EXPECT_TRUE(std::isinf(h.t));
}

TEST_F(RayTracerTest, ClosedMeshFromItsCentreHitsEveryDirectionAtTheAnalyticDistance) {
  const RayTracer t = tracer(kOcta);
  // Every vertex (two zero components) and every edge (one zero component) direction, then
  // random ones: from the centre each must hit, at t = 1/|d|_1, never pass through a seam.
  std::vector<Vec3d> dirs;
  for (int a = -1; a <= 1; ++a) {
    for (int b = -1; b <= 1; ++b) {
      for (int c = -1; c <= 1; ++c) {
        if (a || b || c) dirs.push_back(normalize(Vec3d(a, b, c)));
      }
    }
  }
  std::mt19937_64 rng(18);
  std::normal_distribution<double> g;
  for (int i = 0; i < 20000; ++i) dirs.push_back(normalize(Vec3d(g(rng), g(rng), g(rng))));
  for (const Vec3d& d : dirs) {
    const Vec3f df(d);  // as a float: exercises the unit-length pass-through
    WorldRay r{{0, 0, 0}, Vec3d(df)};
    WorldHit h;
    t.nearest(&r, 1, &h);
    ASSERT_TRUE(h.hit) << "leaked through a seam towards " << d.x << " " << d.y << " " << d.z;
    const Vec3d dd = normalize(Vec3d(df));
    const double want = 1.0 / (std::abs(dd.x) + std::abs(dd.y) + std::abs(dd.z));
    ASSERT_NEAR(h.t, want, 4e-7 * want) << d.x << " " << d.y << " " << d.z;
    // The normal is one of the faces' around the hit: sign-compatible with the direction.
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(std::abs(h.n[k]), 1.0 / std::sqrt(3.0), 1e-6);
      if (dd[k] != 0) {
        ASSERT_GT(h.n[k] * dd[k], 0);
      }
    }
    ASSERT_LT(h.primitive, 8u);
    // Barycentrics inside the triangle (the hit point was interpolated from them).
    ASSERT_GE(h.u, 0.0f);
    ASSERT_GE(h.v, 0.0f);
    ASSERT_LE(h.u + h.v, 1.0f + 1e-6f);
  }
}

TEST_F(RayTracerTest, RaysEnteringThroughSharedEdgesAndVerticesStopThere) {
  const RayTracer t = tracer(kOcta);
  // Each ray enters the octahedron exactly at a vertex or at a point of an edge, heading for a
  // point q inside: on a convex solid the line through p and q is outside before p, so the
  // first hit must be p itself, at t = |p - o|. A leak shows as a later hit or none.
  std::vector<Vec3d> targets;
  for (int k = 0; k < 3; ++k) {
    for (int s : {1, -1}) {
      Vec3d v(0, 0, 0);
      v[k] = s;
      targets.push_back(v);
    }
  }
  for (int i = 1; i < 16; ++i) {
    const double a = i / 16.0;
    for (int sx : {1, -1}) {
      for (int sy : {1, -1}) {
        targets.push_back({sx * a, sy * (1 - a), 0});
        targets.push_back({0, sx * a, sy * (1 - a)});
        targets.push_back({sy * (1 - a), 0, sx * a});
      }
    }
  }
  int rays = 0;
  for (const Vec3d& p : targets) {
    for (const Vec3d& off : {Vec3d(0, 0, 0), Vec3d(0.1, 0.05, -0.08), Vec3d(-0.07, 0.12, 0.04)}) {
      const Vec3d q = p * 0.5 + off;  // |q|_1 <= 0.73: inside
      const Vec3d o = p + (p - q) * 4.0;
      const Vec3d d = normalize(q - o);
      const WorldHit h = nearest(t, o, d);
      ASSERT_TRUE(h.hit) << "passed through at " << p.x << " " << p.y << " " << p.z;
      // Stopping just short of p: nothing in the way (the helper checks occlusion agrees).
      EXPECT_FALSE(nearest(t, o, d, 0.0f, float(length(p - o) * (1 - 1e-4))).hit);
      ASSERT_NEAR(h.t, length(p - o), 1e-5) << p.x << " " << p.y << " " << p.z;
      // Float spacing of render space (world minus the eye, |z| ~ 20 here): 2^-19.
      expect_vec(h.p, p, 4 * 0x1p-19);
      ++rays;
    }
  }
  EXPECT_EQ(rays, 3 * (6 + 15 * 12));
}

TEST_F(RayTracerTest, GrazingRaysHitInsideTheSilhouetteAndMissOutsideIt) {
  const RayTracer t = tracer(kSphere);
  for (double eps : {1e-3, 1e-5}) {
    const double x = 2.0 * (1.0 - eps);
    WorldHit h = nearest(t, {x, 0, 0}, {0, 0, 1});
    ASSERT_TRUE(h.hit) << eps;
    EXPECT_NEAR(h.t, 10.0 - std::sqrt(4.0 - x * x), 1e-4) << eps;
    EXPECT_FALSE(nearest(t, {2.0 * (1.0 + eps), 0, 0}, {0, 0, 1}).hit) << eps;
  }
  // Along the line of an edge, in the planes of both its faces: the only point it shares with
  // the octahedron is the vertex (1, 0, 0), at t = sqrt(2). Either that point or nothing; never
  // a point off the surface, never NaN.
  const RayTracer m = tracer(kOcta);
  const WorldHit h = nearest(m, {2, -1, 0}, {-1, 1, 0});
  if (h.hit) {
    EXPECT_NEAR(h.t, std::sqrt(2.0), 1e-5);
    expect_vec(h.p, {1, 0, 0}, 1e-6);
  } else {
    EXPECT_TRUE(std::isinf(h.t));
  }
}

TEST_F(RayTracerTest, AnimatedScenesAreTracedAtTheRequestedFrame) {
  // The ball rises 0.5 per frame: a ray 2.5 above its first position passes over it at frame 0
  // and meets it at frames 2 and 4, where the sphere's equation says.
  const std::string anim = R"({"frames": 5, "objects": {"ball": [{"frame": 0, "translate": [0, 0, 0]},
                                                                  {"frame": 4, "translate": [0, 2, 0]}]}})";
  for (int frame : {0, 2, 4}) {
    const RayTracer t = tracer(kSphere, "[0, 3, 20]", frame, anim);
    const WorldHit h = nearest(t, {0, 2.5, 0}, {0, 0, 1});
    const double y = 2.5 - 0.5 * frame;  // the ray's height above the ball's centre
    ASSERT_EQ(h.hit, y < 2.0) << frame << " t " << h.t << " p " << h.p.x << " " << h.p.y << " " << h.p.z;
    if (h.hit) {
      EXPECT_NEAR(h.t, 10.0 - std::sqrt(4.0 - y * y), 1e-5) << frame;
    }
  }
}

TEST_F(RayTracerTest, TminAndTmaxBoundTheHitsInterval) {
  const RayTracer t = tracer(kSphere);
  // The renderer's interval is open, (t_min, t_max): a surface at exactly t_max does not block
  // a shadow ray ending on it.
  EXPECT_FALSE(nearest(t, {0, 0, 0}, {0, 0, 1}, 0.0f, 8.0f).hit);
  EXPECT_TRUE(nearest(t, {0, 0, 0}, {0, 0, 1}, 0.0f, std::nextafter(8.0f, 9.0f)).hit);
  const WorldHit far = nearest(t, {0, 0, 0}, {0, 0, 1}, 9.0f);   // starts inside: the far wall
  ASSERT_TRUE(far.hit);
  EXPECT_FLOAT_EQ(far.t, 12.0f);
  expect_vec(Vec3d(far.n), {0, 0, 1}, 1e-6);
  EXPECT_FALSE(nearest(t, {0, 0, 0}, {0, 0, 1}, 12.5f).hit);
}

TEST_F(RayTracerTest, DirectionLengthDoesNotChangeDistances) {
  const RayTracer t = tracer(kSphere);
  for (double len : {1e-300, 1e-3, 1000.0, 1e300}) {
    WorldRay r{{0, 0, 0}, Vec3d(0, 0, len)};
    WorldHit h;
    t.nearest(&r, 1, &h);
    ASSERT_TRUE(h.hit) << len;
    EXPECT_FLOAT_EQ(h.t, 8.0f) << len;
  }
}

TEST_F(RayTracerTest, FarOriginsKeepTheirPrecision) {
  // A small octahedron (radius 0.01) 1e6 units from the ray origins: float origins would be
  // off by ~0.06, missing it entirely; the tracer moves them in double first.
  const RayTracer t = tracer(R"({"type": "mesh", "name": "o", "file": "octa.obj", "material": "d",
      "transform": {"translate": [100, 0, 0], "scale": 0.01}}, )" + std::string(kFloor) + R"(,
      {"type": "plane", "name": "far_wall", "point": [0, -1000, 0], "normal": [0, 1, 0], "material": "d"})",
                                  "[100, 0, 0.5]");
  // Downwards (d.y < 0), so the planes below (y = -1, y = -1000) are not crossed on the way.
  for (const Vec3d& dir : {Vec3d(1, -0.3, 0.2), Vec3d(-0.5, -1, 0.7), Vec3d(0.1, -0.2, 1)}) {
    const Vec3d d = normalize(dir);
    const Vec3d target(100.002, 0.003, 0.001);  // inside the octahedron: aim there
    const Vec3d o = target - d * 1e6;
    const WorldHit h = nearest(t, o, d);
    ASSERT_TRUE(h.hit);
    EXPECT_EQ(t.scene().objects[h.object].name, "o");
    const Vec3d rel = (h.p - Vec3d(100, 0, 0)) * 100.0;
    EXPECT_NEAR(std::abs(rel.x) + std::abs(rel.y) + std::abs(rel.z), 1.0, 1e-4);
    // Distance from the origin to the surface point, to float precision of 1e6.
    EXPECT_NEAR(h.t, length(h.p - o), 0.125);
  }
  // From 1e7 below, straight up: the far wall at y = -1000 lies outside the geometry's cube, so
  // it is found by the query before the move.
  WorldHit h = nearest(t, {100, -1e7, 0}, {0, 1, 0});
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(t.scene().objects[h.object].name, "far_wall");
  EXPECT_NEAR(h.t, 1e7 - 1000, 1.0);
  // Up from y = -500: past the far wall, the floor at -1.
  h = nearest(t, {100.5, -500, 0}, {0, 1, 0});
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(t.scene().objects[h.object].name, "floor");
  EXPECT_NEAR(h.t, 499.0, 1e-4);
}

// Whatever passes check_ray, however extreme, gives a miss or a finite hit on a surface in the
// ray's interval: never a crash, NaN or a point off the ray.
TEST_F(RayTracerTest, ExtremeButValidRaysGiveFiniteAnswers) {
  const RayTracer t = tracer(std::string(kOcta) + ", " + kSphere + ", " + kFloor);
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> expo(-30, 30), unit(-1, 1);
  auto value = [&] { return unit(rng) * std::pow(10.0, expo(rng)); };
  int checked = 0, hits = 0;
  for (int i = 0; i < 20000; ++i) {
    WorldRay r{{value(), value(), value()}, {value(), value(), value()}};
    if (i % 3 == 0) r.o = Vec3d(unit(rng), unit(rng), unit(rng) + 5);  // near the geometry
    if (i % 5 == 0) r.d[i % 3] = 0;
    if (i % 7 == 0) {
      r.tmin = float(std::abs(value()));
      r.tmax = r.tmin * 2;
    }
    if (!check_ray(r, size_t(i)).empty()) continue;
    ++checked;
    WorldHit h, occ;
    t.nearest(&r, 1, &h);
    t.occluded(&r, 1, &occ);
    ASSERT_EQ(occ.hit, h.hit) << i;  // the any-hit traversal agrees, however extreme the ray
    if (!h.hit) {
      ASSERT_TRUE(std::isinf(h.t)) << i;
      continue;
    }
    ++hits;
    ASSERT_TRUE(std::isfinite(h.t) && is_finite(h.p) && is_finite(h.n))
        << i << " o " << r.o.x << " " << r.o.y << " " << r.o.z << " d " << r.d.x << " " << r.d.y << " " << r.d.z
        << " t " << r.tmin << " " << r.tmax << " -> t " << h.t << " p " << h.p.x << " " << h.p.y << " " << h.p.z
        << " object " << h.object;
    ASSERT_GE(h.t, r.tmin) << i;
    ASSERT_LE(h.t, r.tmax) << i;
    ASSERT_NEAR(length(Vec3d(h.n)), 1.0, 1e-5) << i;
    ASSERT_LT(h.object, 3u) << i;
  }
  EXPECT_GT(checked, 19000);
  EXPECT_GT(hits, 2000);
}

template <class T>
bool bits_equal(const T& a, const T& b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}
bool same_bits(const WorldHit& a, const WorldHit& b) {
  return a.hit == b.hit && bits_equal(a.t, b.t) && bits_equal(a.p, b.p) && bits_equal(a.n, b.n) &&
         bits_equal(a.ns, b.ns) && bits_equal(a.u, b.u) && bits_equal(a.v, b.v) && a.object == b.object &&
         a.primitive == b.primitive && a.material == b.material;
}

TEST_F(RayTracerTest, ARaysAnswerDoesNotDependOnItsBatch) {
  const RayTracer t = tracer(std::string(kOcta) + ", " + kSphere + ", " + kFloor);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-3, 3);
  std::vector<WorldRay> rays;
  for (int i = 0; i < 257; ++i) {
    rays.push_back({{u(rng), u(rng), u(rng) + 5}, normalize(Vec3d(u(rng), u(rng), u(rng)))});
  }
  std::vector<WorldHit> all(rays.size());
  t.nearest(rays.data(), rays.size(), all.data());
  std::vector<WorldHit> occ(rays.size());
  t.occluded(rays.data(), rays.size(), occ.data());
  int hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    WorldHit one;
    t.nearest(&rays[i], 1, &one);
    ASSERT_TRUE(same_bits(one, all[i])) << i;
    ASSERT_EQ(occ[i].hit, all[i].hit) << i;
    hits += all[i].hit;
  }
  EXPECT_GT(hits, 50);  // the batch exercises hits, not only misses
}

// nearest() and occluded() trace batches with SIMD code compiled for each target the machine has
// (world_batch.h, render/ray_batch.h); a single ray takes the scalar path (trace(), blocked()). On
// every target, each ray of a batch must get the single ray's answer bit for bit: over opaque and glass
// triangles, a mesh with vertex normals, a sphere, two planes, directions of any length, t
// intervals, far origins and rays that miss.
TEST_F(RayTracerTest, BatchesAnswerAsSingleRaysOnEverySimdTarget) {
  const std::string objects = std::string(kOcta) + ", " + kSphere + ", " + kFloor + R"(,
    {"type": "mesh", "name": "glass_octa", "file": "octa.obj", "material": "g",
     "transform": {"translate": [3, 0, 4]}},
    {"type": "mesh", "name": "smooth_octa", "file": "octa.obj", "material": "d",
     "transform": {"translate": [-3, 0.5, 2], "scale": 1.5}},
    {"type": "plane", "name": "wall", "point": [0, 0, -6], "normal": [0, 0.2, 1], "material": "d"})";
  const std::string json = R"({"camera": {"position": [0, 3, 20], "look_at": [0, 0, 0]},
    "materials": {"d": {"type": "diffuse"}, "g": {"type": "glass"}}, "objects": [)" + objects + "]}";
  std::ofstream(dir_ / "s.json") << json;
  auto scene = std::make_shared<Scene>(load_scene((dir_ / "s.json").string()));
  // The smooth octahedron gets vertex normals (as glTF NORMAL would give it): shading normals.
  for (const SceneObject& obj : scene->objects) {
    if (obj.name != "smooth_octa") continue;
    Mesh& m = scene->meshes[size_t(obj.mesh)];
    m.normals.clear();
    for (const Vec3f& p : m.positions) m.normals.push_back(normalize(p + Vec3f(0.1f, 0.2f, 0.3f)));
  }
  const RayTracer t(scene, make_render_scene(*scene, 0));

  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<WorldRay> rays;
  for (int i = 0; i < 3000; ++i) {
    WorldRay r;
    r.o = {6 * u(rng), 3 + 4 * u(rng), 8 + 10 * u(rng)};
    Vec3d target(4 * u(rng), 2 * u(rng), 2 + 6 * u(rng));
    if (i % 7 == 0) target = r.o + Vec3d(u(rng), u(rng), u(rng));  // anywhere: many miss
    const double scale[] = {1.0, 1.0, 1.0, 0.25, 7.0, 1e-3, 1e4};
    r.d = normalize(target - r.o) * scale[i % 7];
    if (i % 5 == 1) r.tmin = float(2 * (1 + u(rng)));
    if (i % 5 == 2) r.tmax = float(8 * (1 + u(rng)));
    if (i % 97 == 3) {  // from far away, towards the scene: moved in double by query()
      r.o = Vec3d(3e6, -2e6, 5e6);
      r.d = target - r.o;
    }
    rays.push_back(r);
  }
  std::vector<WorldHit> single(rays.size()), single_occ(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    t.nearest(&rays[i], 1, &single[i]);
    t.occluded(&rays[i], 1, &single_occ[i]);
    ASSERT_EQ(single_occ[i].hit, single[i].hit) << "ray " << i;
  }
  std::map<uint32_t, int> hits_by_object;
  for (const WorldHit& h : single) hits_by_object[h.hit ? h.object : kNoIndex]++;
  for (uint32_t k = 0; k < uint32_t(scene->objects.size()); ++k) {
    EXPECT_GE(hits_by_object[k], 20) << "object " << scene->objects[k].name << " is hardly hit: the test is weak";
  }
  EXPECT_GE(hits_by_object[kNoIndex], 100);

  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    for (size_t batch : {size_t(4), size_t(61), size_t(64), size_t(3000)}) {
      std::vector<WorldHit> got(rays.size());
      for (size_t b = 0; b < rays.size(); b += batch) t.nearest(&rays[b], std::min(batch, rays.size() - b), &got[b]);
      std::vector<WorldHit> occ(rays.size());
      for (size_t b = 0; b < rays.size(); b += batch) t.occluded(&rays[b], std::min(batch, rays.size() - b), &occ[b]);
      for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_TRUE(same_bits(got[i], single[i])) << "ray " << i << " in batches of " << batch;
        ASSERT_EQ(occ[i].hit, single_occ[i].hit) << "occlusion, ray " << i << " in batches of " << batch;
      }
    }
    // nearest_into(): the same answers written into response-style arrays (vectors of them at a
    // time, the rest one by one), at an offset, in pieces of 700 (10 batches and 60 rays), nothing
    // outside a piece's range; arrays not given are not written.
    const size_t N = rays.size(), off = 5;
    std::vector<char> hit(N + off, 7);
    std::vector<float> tt(N + off), nn(3 * (N + off)), ns(3 * (N + off)), uv(2 * (N + off));
    std::vector<double> pp(3 * (N + off));
    std::vector<uint32_t> obj(N + off), prim(N + off), mat(N + off);
    const HitColumns all{hit.data(), tt.data(), pp.data(), nn.data(), ns.data(), uv.data(), obj.data(), prim.data(), mat.data()};
    // Last piece first: a piece that wrote past its end would overwrite the next one's answers.
    for (size_t b = (N - 1) / 700 * 700;; b -= 700) {
      t.nearest_into(&rays[b], std::min<size_t>(700, N - b), all, off + b);
      if (b == 0) break;
    }
    HitColumns some;
    std::vector<float> t_only(N);
    some.t = t_only.data();
    t.nearest_into(rays.data(), N, some, 0);
    for (size_t i = 0; i < N; ++i) {
      const size_t k = off + i;
      WorldHit got;
      got.hit = hit[k] == 1;
      ASSERT_TRUE(hit[k] == 0 || hit[k] == 1) << i;
      got.t = tt[k];
      got.p = {pp[3 * k], pp[3 * k + 1], pp[3 * k + 2]};
      got.n = {nn[3 * k], nn[3 * k + 1], nn[3 * k + 2]};
      got.ns = {ns[3 * k], ns[3 * k + 1], ns[3 * k + 2]};
      got.u = uv[2 * k];
      got.v = uv[2 * k + 1];
      got.object = obj[k];
      got.primitive = prim[k];
      got.material = mat[k];
      ASSERT_TRUE(same_bits(got, single[i])) << "nearest_into, ray " << i;
      ASSERT_TRUE(bits_equal(t_only[i], single[i].t)) << "nearest_into with t alone, ray " << i;
    }
    for (size_t k = 0; k < off; ++k) EXPECT_EQ(hit[k], 7) << "written before the offset";
  }
  hwy::SetSupportedTargetsForTest(0);
}

// The renderer's primary hits for every camera ray of one frame (spp 4: packets of four, as the
// renderer traces them), against the tracer given the same rays in world space.
void expect_camera_rays_agree(const std::string& scene_file, int width, int height) {
  auto scene = std::make_shared<Scene>(load_scene(std::string(TESSERA_SOURCE_DIR) + "/" + scene_file));
  scene->image.width = width;
  scene->image.height = height;
  scene->image.spp = 4;
  scene->image.max_depth = 0;
  auto rs = make_render_scene(*scene, 0);
  RayLog log;
  thread_ray_log() = &log;
  render_tile(*rs, {0, 0, width, height});
  thread_ray_log() = nullptr;
  std::vector<Ray> camera;
  for (const LoggedRay& l : log.rays) {
    if (l.kind != LoggedRay::Kind::kCamera) continue;
    camera.push_back({Vec3f(l.ray.org_x, l.ray.org_y, l.ray.org_z), Vec3f(l.ray.dir_x, l.ray.dir_y, l.ray.dir_z)});
  }
  ASSERT_EQ(camera.size(), size_t(width) * size_t(height) * 4);
  const RayTracer tracer(scene, rs);
  size_t hits = 0;
  for (size_t i = 0; i < camera.size(); i += 4) {
    Hit want[4];
    bool found[4];
    const PrimRef from[4];
    rs->intersect_packet(&camera[i], from, 4, want, found);
    WorldRay w[4];
    for (int k = 0; k < 4; ++k) w[k] = {rs->origin() + Vec3d(camera[i + size_t(k)].o), Vec3d(camera[i + size_t(k)].d)};
    WorldHit got[4];
    tracer.nearest(w, 4, got);
    for (int k = 0; k < 4; ++k) {
      ASSERT_EQ(got[k].hit, found[k]) << scene_file << " ray " << i + size_t(k);
      if (!found[k]) continue;
      ++hits;
      // Bit for bit: t, the normal, the render-space point, the primitive and material.
      ASSERT_TRUE(bits_equal(got[k].t, want[k].t)) << i + size_t(k);
      ASSERT_TRUE(bits_equal(got[k].n, want[k].n)) << i + size_t(k);
      ASSERT_TRUE(bits_equal(got[k].u, want[k].u) && bits_equal(got[k].v, want[k].v)) << i + size_t(k);
      ASSERT_EQ(got[k].p, rs->origin() + Vec3d(want[k].p)) << i + size_t(k);
      ASSERT_EQ(got[k].material, want[k].material);
      ASSERT_EQ(got[k].object, rs->source_of(want[k].prim).object);
      ASSERT_EQ(got[k].primitive, rs->source_of(want[k].prim).primitive);
    }
  }
  EXPECT_GT(hits, camera.size() / 4) << "the frame should be mostly surfaces";
}

TEST(RayTracerAgreement, WhittedCameraRaysHitWhatTheRendererHits) {
  expect_camera_rays_agree("scenes/whitted.json", 240, 135);
}

TEST(RayTracerAgreement, BunnyCameraRaysHitWhatTheRendererHits) {
  expect_camera_rays_agree("scenes/bunny.json", 160, 120);
}

}  // namespace
}  // namespace tessera::rays

// SPDX-License-Identifier: Apache-2.0
#include "render/render_scene_internal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "scene/scene_parser.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

class RenderSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_rs_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    // A closed unit cube (outward CCW winding), two triangles per face.
    std::ofstream obj(dir_ / "cube.obj");
    obj << "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
           "f 1 4 3\nf 1 3 2\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 8 7\nf 4 7 3\n"
           "f 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n";
  }
  void TearDown() override { fs::remove_all(dir_); }

  Scene load(const std::string& objects, const std::string& materials = R"({"d": {"type": "diffuse"},
      "g": {"type": "glass", "ior": 1.5, "transmittance": [0.5, 0.25, 1]}})") {
    const std::string json = R"({"camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
      "materials": )" + materials + R"(, "objects": [)" + objects + "]}";
    std::ofstream(dir_ / "s.json") << json;
    return load_scene((dir_ / "s.json").string());
  }

  fs::path dir_;
};

// Rays are given in world space here; render space is world minus the eye (0, 0, 10).
Ray world_ray(const Vec3d& o, const Vec3d& d, float tmax = INFINITY) {
  return {Vec3f(o - Vec3d{0, 0, 10}), Vec3f(normalize(d)), tmax};
}

TEST_F(RenderSceneTest, TriangleMeshIsHitFromOutsideAndInsideWithOutwardNormals) {
  RenderScene rs(load(R"({"type": "mesh", "file": "cube.obj", "material": "d"})"), 0);
  Hit h;
  ASSERT_TRUE(rs.intersect(world_ray({0.3, 0.2, 5}, {0, 0, -1}), {}, &h));
  EXPECT_NEAR(h.t, 4.0f, 1e-5f);
  EXPECT_NEAR(h.n.z, 1.0f, 1e-6f);  // +z face, outward
  ASSERT_TRUE(rs.intersect(world_ray({0.3, 0.2, 0}, {0, 0, -1}), {}, &h));  // from inside
  EXPECT_NEAR(h.t, 1.0f, 1e-5f);
  EXPECT_NEAR(h.n.z, -1.0f, 1e-6f);  // -z face, still outward
  EXPECT_FALSE(rs.intersect(world_ray({3, 0, 5}, {0, 0, -1}), {}, &h));
}

TEST_F(RenderSceneTest, RaysThroughSharedEdgesAndVerticesNeverLeak) {
  RenderScene rs(load(R"({"type": "mesh", "file": "cube.obj", "material": "d"})"), 0);
  Hit h;
  // Aimed exactly at the diagonal edge shared by the two +z triangles, and at a corner.
  for (double s = -0.9; s <= 0.9; s += 0.05) {
    ASSERT_TRUE(rs.intersect(world_ray({s, s, 5}, {0, 0, -1}), {}, &h)) << s;
  }
  ASSERT_TRUE(rs.intersect(world_ray({3, 3, 3}, {-1, -1, -1}), {}, &h));
  EXPECT_NEAR(h.t, float(std::sqrt(12.0)), 1e-5f);
}

// The box padding of the watertight mode scales with the triangles' reach, never with a huge
// sphere's: a 1e6 ground sphere once widened every triangle's box by ~30 units and made a bunny
// scene 1000x slower (the BVH could no longer cull). Mesh hits are unchanged by the sphere.
TEST_F(RenderSceneTest, BoxPaddingIgnoresHugeSpheres) {
  const std::string cube = R"({"type": "mesh", "file": "cube.obj", "material": "d"})";
  const RenderScene alone(load(cube), 0);
  const RenderScene with_ground(
      load(cube + R"(, {"type": "sphere", "center": [0, -1000002, 0], "radius": 1e6, "material": "d"})"), 0);
  EXPECT_EQ(with_ground.box_padding(1.0f), alone.box_padding(1.0f));
  EXPECT_LT(alone.box_padding(1.0f), 1e-3f);
  Hit a, b;
  const Ray r = world_ray({0.25, 0.5, 5}, {0, 0, -1});
  ASSERT_TRUE(alone.intersect(r, {}, &a));
  ASSERT_TRUE(with_ground.intersect(r, {}, &b));
  EXPECT_EQ(a.t, b.t);
  EXPECT_EQ(a.prim.kind, PrimRef::Kind::kTriangle);
  // The ground is still found below the cube.
  ASSERT_TRUE(with_ground.intersect(world_ray({3, 0, 0}, {0, -1, 0}), {}, &b));
  EXPECT_EQ(b.prim.kind, PrimRef::Kind::kSphere);
  EXPECT_NEAR(b.t, 2.0f, 1e-3f);
}

TEST_F(RenderSceneTest, RayParallelToAFaceInItsPlaneDoesNotProduceGarbage) {
  RenderScene rs(load(R"({"type": "mesh", "file": "cube.obj", "material": "d"})"), 0);
  Hit h;
  // Travels inside the plane z = 1 of the +z face, towards the cube: it may graze the face or
  // hit the side face at x = -1; either way t is finite, >= 0 and the point is on the cube.
  if (rs.intersect(world_ray({-5, 0, 1}, {1, 0, 0}), {}, &h)) {
    EXPECT_TRUE(std::isfinite(h.t));
    EXPECT_GE(h.t, 0.0f);
    EXPECT_NEAR(h.t, 4.0f, 1e-4f);
  }
}

TEST_F(RenderSceneTest, SphereTransformScalesAndMovesIt) {
  RenderScene rs(load(R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "d",
                          "transform": {"scale": 2, "translate": [1, 0, 0]}})"), 0);
  Hit h;
  ASSERT_TRUE(rs.intersect(world_ray({1, 0, 5}, {0, 0, -1}), {}, &h));
  EXPECT_NEAR(h.t, 3.0f, 1e-5f);
  EXPECT_NEAR(h.n.z, 1.0f, 1e-6f);
  EXPECT_FALSE(rs.intersect(world_ray({3.01, 0, 5}, {0, 0, -1}), {}, &h));
}

TEST_F(RenderSceneTest, RaysLeavingASphereNeverReHitItButRefractedRaysFindTheFarSide) {
  RenderScene rs(load(R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "g"})"), 0);
  Hit h;
  ASSERT_TRUE(rs.intersect(world_ray({0.2, 0.1, 5}, {0, 0, -1}), {}, &h));
  const Hit first = h;
  // Outward from the hit point, tangentially-ish: must not hit the same sphere.
  const Vec3f out = normalize(first.n + Vec3f{0.3f, 0, 0});
  Ray r{offset_ray_origin(first.p, first.p_err, first.n, out), out};
  EXPECT_FALSE(rs.intersect(r, first.prim, &h));
  // Inward: the far side, at the chord length.
  const Vec3f in{0, 0, -1};
  r = {offset_ray_origin(first.p, first.p_err, first.n, in), in};
  ASSERT_TRUE(rs.intersect(r, first.prim, &h));
  const double z = std::sqrt(1 - 0.2 * 0.2 - 0.1 * 0.1);
  EXPECT_NEAR(h.t, 2 * z, 1e-5);
}

TEST_F(RenderSceneTest, ShadowRaysPassThroughGlassAttenuatedPerCrossing) {
  RenderScene rs(load(R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "g"},
                         {"type": "sphere", "center": [0, 5, 0], "radius": 1, "material": "d"})"), 0);
  // Through the glass sphere: two crossings, T^2 per channel.
  const Rgb T = rs.transmittance(world_ray({0, 0, 5}, {0, 0, -1}, 10), {});
  EXPECT_FLOAT_EQ(T.x, 0.25f);
  EXPECT_FLOAT_EQ(T.y, 0.0625f);
  EXPECT_FLOAT_EQ(T.z, 1.0f);
  // Stopping inside the glass: one crossing.
  const Rgb T1 = rs.transmittance(world_ray({0, 0, 5}, {0, 0, -1}, 4.5f), {});
  EXPECT_FLOAT_EQ(T1.x, 0.5f);
  // The opaque sphere blocks completely; a ray ending before it does not see it.
  EXPECT_EQ(rs.transmittance(world_ray({0, 5, 5}, {0, 0, -1}, 10), {}), Rgb(0.0f));
  EXPECT_EQ(rs.transmittance(world_ray({0, 5, 5}, {0, 0, -1}, 3.5f), {}), Rgb(1.0f));
}

TEST_F(RenderSceneTest, PlanesAreExcludedOnlyForRaysLeavingThem) {
  RenderScene rs(load(R"({"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "d"})"), 0);
  Hit h;
  ASSERT_TRUE(rs.intersect(world_ray({0, 2, 0}, {0, -1, 0}), {}, &h));
  EXPECT_NEAR(h.t, 3.0f, 1e-6f);
  EXPECT_EQ(h.prim.kind, PrimRef::Kind::kPlane);
  // A ray leaving the plane downward (through it) never meets it again.
  EXPECT_FALSE(rs.intersect({h.p, Vec3f{0, -1, 0}}, h.prim, &h));
}

// The floor's checker against its definition, in double with divisions: parity of
// floor(x / s) + floor(-z / s) in the plane's basis (x, -z for an upward floor at the origin), for
// scales that are powers of two (taken by a multiplication with the exact reciprocal) and scales
// that are not, at points inside squares and exactly on their edges.
TEST_F(RenderSceneTest, CheckerParityIsTheDefinitionAtEveryScale) {
  for (const double scale : {1.0, 0.25, 4.0, 0.5, 0.3, 3.0, 1e-3}) {
    const std::string materials = R"({"c": {"type": "diffuse", "checker": {"albedo2": [1, 1, 1], "scale": )" +
                                  std::to_string(scale) + "}}}";
    const Scene scene = load(R"({"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "c"})", materials);
    RenderScene rs(scene, 0);
    const double s = scene.materials[0].checker_scale;
    int odd = 0, n = 0;
    for (int i = -3200; i <= 3200; i += 37) {
      for (int j = -3200; j <= 3200; j += 41) {
        // World points on a 1/64 grid (exact in float), and multiples of the scale (square edges).
        for (const auto& [x, z] : {std::pair{i / 64.0, j / 64.0}, std::pair{(i / 64) * s, (j / 64) * s}}) {
          Hit h;
          h.p = Vec3f(float(x), 0.0f, float(z - 10.0));  // render space: world minus the eye (0, 0, 10)
          if (double(h.p.x) != x || double(h.p.z) != z - 10.0) continue;
          h.prim = {PrimRef::Kind::kPlane, 0, 0};
          const int want = int(int64_t(std::floor(x / s) + std::floor(-z / s)) & 1);
          ASSERT_EQ(rs.checker_parity(h, scene.materials[0]), want) << "scale " << scale << " at " << x << ", " << z;
          odd += want;
          ++n;
        }
      }
    }
    EXPECT_GT(n, 20000);
    EXPECT_GT(odd, n / 4) << "both colours seen";
    EXPECT_LT(odd, 3 * n / 4);
  }
}

}  // namespace
}  // namespace tessera

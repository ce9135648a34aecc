// SPDX-License-Identifier: Apache-2.0
// Interpolated shading normals against analytic values. A sphere mesh whose vertex normals are
// the sphere's radial normals interpolates to the true sphere normal at every hit point
// (sum b_i (v_i - c) / r = (p - c) / r, since p = sum b_i v_i), while its facets are off by up
// to half a facet's angle; the terminator term and the side rules keep light and rays on the
// geometric surface's side.
#include "render/shading_normal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>

#include "render/fresnel.h"
#include "render/render_scene_internal.h"
#include "render/tile_renderer.h"
#include "support/gltf_test_builder.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using testing::GltfBuilder;

double angle(const Vec3d& a, const Vec3d& b) {
  return std::atan2(length(cross(a, b)), dot(a, b));
}

// A UV sphere of `stacks` x `slices` around `c` with radius r; `normals` gets the radial
// normals when not null.
void uv_sphere(const Vec3d& c, double r, int stacks, int slices, std::vector<float>* pos, std::vector<uint32_t>* idx,
               std::vector<float>* normals) {
  for (int i = 0; i <= stacks; ++i) {
    const double th = std::numbers::pi * i / stacks;
    for (int j = 0; j < slices; ++j) {
      const double ph = 2 * std::numbers::pi * j / slices;
      const Vec3d n(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
      const Vec3d p = c + n * r;
      pos->insert(pos->end(), {float(p.x), float(p.y), float(p.z)});
      if (normals) {
        // The normal of the vertex as stored (rounded to float), so the identity is exact up to rounding.
        const Vec3d q = Vec3d(float(p.x), float(p.y), float(p.z)) - c;
        const Vec3d u = q / length(q);
        normals->insert(normals->end(), {float(u.x), float(u.y), float(u.z)});
      }
    }
  }
  auto at = [&](int i, int j) { return uint32_t(i * slices + (j % slices)); };
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      // Counter-clockwise seen from outside: the winding normal points out.
      if (i > 0) idx->insert(idx->end(), {at(i, j), at(i, j + 1), at(i + 1, j)});
      if (i + 1 < stacks) idx->insert(idx->end(), {at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)});
    }
  }
}

class ShadingNormalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_shading_normal_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  Scene sphere_scene(bool with_normals, int width = 48) {
    GltfBuilder b;
    std::vector<float> pos, nrm;
    std::vector<uint32_t> idx;
    uv_sphere(kCenter, 1.0, 10, 20, &pos, &idx, with_normals ? &nrm : nullptr);
    const int grey = b.material({{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1}}, {"metallicFactor", 0}}}});
    b.node({{"mesh", b.mesh(pos, idx, grey, {}, nrm)}});
    b.node({{"camera", b.camera(0.7, 1)}, {"translation", {0, 0, 5}}});
    b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "point"}, {"intensity", 6830}})}}}}},
            {"translation", {2, 1.5, 3}}});
    b.write((dir_ / "s.gltf").string());
    Scene s = load_scene((dir_ / "s.gltf").string());
    ImageOverrides o;
    o.width = o.height = width;
    o.spp = 1;
    o.sampler = SamplerKind::kCenter;
    apply_overrides(s, o);
    return s;
  }
  const Vec3d kCenter{0.25, -0.125, 0.0};
  fs::path dir_;
};

TEST_F(ShadingNormalTest, SphereMeshShadingNormalIsTheTrueSphereNormal) {
  const Scene scene = sphere_scene(true);
  const RenderScene rs(scene, 0);
  const Vec3d c = kCenter - rs.origin();  // render space
  double worst_shading = 0, worst_facet = 0;
  int hits = 0;
  for (int i = 0; i < 41; ++i) {
    for (int j = 0; j < 41; ++j) {
      // Rays from the eye at a grid of points inside the sphere's silhouette.
      const Vec3d target = c + Vec3d((i - 20) / 21.0, (j - 20) / 21.0, 0);
      const Vec3d d = normalize(target);
      Hit h;
      if (!rs.intersect(Ray{Vec3f(0.0f), Vec3f(d)}, PrimRef{}, &h)) continue;
      ++hits;
      ASSERT_TRUE(h.smooth);
      const Vec3d truth = normalize(Vec3d(h.p) - c);
      worst_shading = std::max(worst_shading, angle(Vec3d(h.ns), truth));
      worst_facet = std::max(worst_facet, angle(Vec3d(h.n), truth));
      EXPECT_NEAR(length(Vec3d(h.ns)), 1.0, 1e-6);
    }
  }
  ASSERT_GT(hits, 1000);
  RecordProperty("worst_angle_shading_rad", std::to_string(worst_shading));
  RecordProperty("worst_angle_facet_rad", std::to_string(worst_facet));
  // Float rounding of vertices, normals and the hit point: a few 1e-7 radians.
  EXPECT_LT(worst_shading, 2e-5) << "facets are off by up to " << worst_facet;
  // The facets of a 10 x 20 sphere: up to about half of a slice's 18 degrees; the test can tell.
  EXPECT_GT(worst_facet, 0.1);
}

TEST_F(ShadingNormalTest, MeshWithoutNormalsShadesFlatAndTheRaysAgree) {
  const Scene smooth = sphere_scene(true), flat = sphere_scene(false);
  const RenderScene a(smooth, 0), b(flat, 0);
  for (int i = 0; i < 200; ++i) {
    const Vec3f d = normalize(Vec3f(float(kCenter.x) + (i % 20 - 10) / 12.0f, float(kCenter.y) + (i / 20 - 5) / 6.0f, -5));
    Hit ha, hb;
    const bool fa = a.intersect(Ray{Vec3f(0.0f), d}, PrimRef{}, &ha), fb = b.intersect(Ray{Vec3f(0.0f), d}, PrimRef{}, &hb);
    ASSERT_EQ(fa, fb);
    if (!fa) continue;
    EXPECT_FALSE(hb.smooth);
    // Normals change shading only: the same triangle, point and geometric normal.
    EXPECT_EQ(ha.t, hb.t);
    EXPECT_EQ(ha.p, hb.p);
    EXPECT_EQ(ha.n, hb.n);
    EXPECT_EQ(ha.prim, hb.prim);
  }
}

// Lambert's law on a smooth sphere under a point light, against the analytic sphere: the
// smooth mesh's pixels are closer to it than the faceted mesh's, away from the terminator.
TEST_F(ShadingNormalTest, SmoothSphereRendersCloserToTheAnalyticSphere) {
  const Scene smooth = sphere_scene(true, 64), flat = sphere_scene(false, 64);
  const RenderScene rs(smooth, 0), rf(flat, 0);
  const ImageRGB is = render_frame(rs, 16, 1).image, jf = render_frame(rf, 16, 1).image;
  // Analytic: a diffuse point with albedo 0.5 lit by I = 6830 / 683 = 10 (cd at 683 lm/W) at
  // distance r, cos theta: L = 0.5 / pi * I cos / r^2 (no shadowing on a convex sphere).
  const Vec3d light = Vec3d(2, 1.5, 3) - rs.origin(), c = kCenter - rs.origin();
  double err_s = 0, err_f = 0;
  int n = 0;
  const auto& cam = rs.camera();
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const Vec3f pf = cam.p0 + cam.du * ((x + 0.5f) / 64) + cam.dv * ((y + 0.5f) / 64);
      const Vec3d d = normalize(Vec3d(pf));
      // The pixel's ray against the true sphere (the mesh is inscribed: its points are within 5% of r).
      const double bq = dot(d, c), disc = bq * bq - (dot(c, c) - 1.0);
      if (disc <= 0) continue;
      const Vec3d p = d * (bq - std::sqrt(disc)), nrm = normalize(p - c);
      const Vec3d to = light - p;
      const double cos_t = dot(nrm, normalize(to));
      if (cos_t < 0.3 || disc < 0.15) continue;  // away from the terminator and the silhouette
      const double L = 0.5 / std::numbers::pi * 10 * cos_t / dot(to, to);
      const size_t k = 3 * (size_t(y) * 64 + x);
      err_s += std::abs(is.rgb[k] - L) / L;
      err_f += std::abs(jf.rgb[k] - L) / L;
      ++n;
    }
  }
  ASSERT_GT(n, 300);
  err_s /= n;
  err_f /= n;
  RecordProperty("mean_relative_error_smooth", std::to_string(err_s));
  RecordProperty("mean_relative_error_flat", std::to_string(err_f));
  // The remaining error is the inscribed mesh's points lying inside the sphere (a few %).
  EXPECT_LT(err_s, 0.5 * err_f) << "smooth " << err_s << ", flat " << err_f;
  EXPECT_LT(err_s, 0.03);
}

TEST(ShadingNormal, TerminatorTermIsCosineWhereNormalsAgreeAndFadesAtTheFacetHorizon) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  const Vec3f ng(0, 0, 1);
  for (int i = 0; i < 2000; ++i) {
    const Vec3f w = normalize(Vec3f(u(rng), u(rng), u(rng)));
    // Equal normals: the plain cosine (G = 1), 0 below.
    EXPECT_NEAR(smooth_light_cosine(ng, ng, w), std::max(0.0f, w.z), 1e-6f);
    // A bent shading normal: never negative, never above its own cosine, and 0 below either
    // surface; near the facet's horizon at most 2 cos_g / (ng.ns) (G' <= 2G), so it fades to 0.
    const Vec3f ns = normalize(Vec3f(0.5f * u(rng), 0.5f * u(rng), 1));
    const float c = smooth_light_cosine(ng, ns, w);
    EXPECT_GE(c, 0.0f);
    EXPECT_LE(c, std::max(0.0f, dot(ns, w)) + 1e-6f);
    if (w.z <= 0 || dot(ns, w) <= 0) {
      EXPECT_EQ(c, 0.0f);
    } else {
      EXPECT_LE(c, 2 * w.z / dot(ng, ns) + 1e-6f);
    }
  }
}

TEST(ShadingNormal, ReflectionsAndRefractionsStayOnTheirSideOfTheFacet) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  const Vec3f ng(0, 0, 1);
  int mirrored = 0;
  for (int i = 0; i < 5000; ++i) {
    const Vec3f d = normalize(Vec3f(u(rng), u(rng), -std::abs(u(rng)) - 1e-3f));  // arrives from above
    const Vec3f ns = normalize(Vec3f(0.8f * u(rng), 0.8f * u(rng), 1));
    const Vec3f n = turning_normal(ng, ns, d);
    EXPECT_LT(dot(d, n), 0.0f);  // the normal the ray turns about is never seen from behind
    const Vec3f r0 = normalize(reflect(d, n));
    const Vec3f r = keep_side(r0, ng, true, normalize(reflect(d, ng)));
    EXPECT_GT(dot(r, ng), 0.0f);
    EXPECT_NEAR(length(r), 1.0f, 1e-5f);
    mirrored += r.x != r0.x || r.y != r0.y || r.z != r0.z;
    // Mirroring about the facet keeps the tangential part: continuous where r0 meets the facet.
    EXPECT_NEAR(r.x, r0.x, 1e-5f);
    EXPECT_NEAR(r.y, r0.y, 1e-5f);
    float cos_t = 0;
    const float cos_i = -dot(d, n);
    if (fresnel_dielectric(cos_i, 1.0f, 1.5f, &cos_t) < 1.0f) {
      const Vec3f t = keep_side(refract(d, n, 1 / 1.5f, cos_i, cos_t), ng, false, d);
      EXPECT_LT(dot(t, ng), 0.0f);
    }
  }
  EXPECT_GT(mirrored, 50);  // bent normals do send some reflections below the facet
}

TEST(ShadingNormal, FlatOrCancellingVertexNormalsGiveNoShadingNormal) {
  std::vector<float> n;
  append_vertex_normals(&n, 1, {Vec3d(0, 0, 2), Vec3d(0, 0, 1), Vec3d(0, 0, 0)});  // one missing: flat
  ASSERT_EQ(n.size(), 18u);
  Vec3f ns(7, 7, 7);
  EXPECT_FALSE(interpolate_shading_normal(&n[0], 1, 0, 0, Vec3f(0, 0, 1), &ns));  // the padded triangle
  EXPECT_FALSE(interpolate_shading_normal(&n[9], 0.3f, 0.3f, 0.4f, Vec3f(0, 0, 1), &ns));
  EXPECT_EQ(ns, Vec3f(7, 7, 7));
  n.clear();
  append_vertex_normals(&n, 0, {Vec3d(1, 0, 0), Vec3d(-1, 0, 0), Vec3d(0, 0, -3)});
  EXPECT_FALSE(interpolate_shading_normal(&n[0], 0.5f, 0.5f, 0.0f, Vec3f(0, 0, 1), &ns));  // cancels
  ASSERT_TRUE(interpolate_shading_normal(&n[0], 0, 0, 1, Vec3f(0, 0, 1), &ns));
  EXPECT_EQ(ns, Vec3f(0, 0, 1));  // the file's (0, 0, -1), turned to the winding's side
}

}  // namespace
}  // namespace tessera

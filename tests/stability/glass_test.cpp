// SPDX-License-Identifier: Apache-2.0
// Case 6: glass against closed forms. A slab at normal incidence transmits (1-R)/(1+R) with all
// internal bounces and exactly the partial sum at each max_depth; a camera under water sees
// Snell's window at asin(1/n), with the exact Fresnel reflectance inside it and lossless total
// internal reflection outside; an ior-1 sphere leaves a lit, textured scene unchanged.
// (Uniform-background invisibility and energy conservation of a glass sphere are in
// lib/render/tile_renderer_test.cpp; the grazing-angle partial sums are in
// self_intersection_test.cpp.) These scenes trace every branch of the tree (roulette_weight 0):
// their claims are the tree's arithmetic, one path at a time, which the roulette's random cut
// keeps only on average.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "render/integrator.h"
#include "scene/animation.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

// Exact unpolarized Fresnel reflectance in double (Born & Wolf), independent of fresnel.h.
double fresnel(double cos_i, double n_i, double n_t) {
  const double sin_t = n_i / n_t * std::sqrt(std::max(0.0, 1 - cos_i * cos_i));
  if (sin_t >= 1) return 1;
  const double cos_t = std::sqrt(1 - sin_t * sin_t);
  const double rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
  const double rp = (n_t * cos_i - n_i * cos_t) / (n_t * cos_i + n_i * cos_t);
  return 0.5 * (rs * rs + rp * rp);
}

// A glass slab between the planes z = 0 and z = -1 (outward normals), an emissive wall behind it
// (z = -3, facing +z), black background: the camera at z = 5 sees the wall only through the slab.
std::string slab_scene(double ior, int max_depth) {
  return R"({
    "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "vfov_deg": 0.001},
    "image": {"width": 1, "height": 1, "spp": 1, "sampler": "center", "roulette_weight": 0, "max_depth": )" +
         std::to_string(max_depth) + R"(},
    "materials": {"g": {"type": "glass", "ior": )" + std::to_string(ior) + R"(},
                  "wall": {"type": "diffuse", "albedo": 0, "emission": 3}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "g"},
                {"type": "plane", "point": [0, 0, -1], "normal": [0, 0, -1], "material": "g"},
                {"type": "mesh", "file": "wall.obj", "material": "wall"}]})";
}

class GlassTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("glass");
    // A 200 x 200 quad at z = -3, counter-clockwise seen from +z (its emitting front).
    write_text(dir_ + "/wall.obj", "v -100 -100 -3\nv 100 -100 -3\nv 100 100 -3\nv -100 100 -3\nf 1 2 3\nf 1 3 4\n");
    // A 40 x 40 quad at y = -2 facing +y (the floor under water).
    write_text(dir_ + "/floor.obj", "v -20 -2 -20\nv -20 -2 20\nv 20 -2 20\nv 20 -2 -20\nf 1 2 3\nf 1 3 4\n");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

TEST_F(GlassTest, SlabAtNormalIncidenceGivesEveryPartialSumExactly) {
  for (double ior : {1.5, 2.4, 9.0}) {
    const double R = std::pow((ior - 1) / (ior + 1), 2);
    double worst = 0;
    for (int depth = 0; depth <= 24; ++depth) {
      // Paths making k round trips inside hit the slab at depths 0 .. 2k+1 and reach the wall
      // at depth 2k+2; each of those hits must be allowed to recurse: 2k+1 < max_depth.
      double partial = 0;
      for (int k = 0; 2 * k + 1 < depth; ++k) partial += (1 - R) * (1 - R) * std::pow(R, 2 * k);
      RenderScene rs(scene_from(slab_scene(ior, depth), dir_ + "/slab.json"), 0);
      const FrameResult r = render_frame(rs, 1, 1);
      const double got = r.image.rgb[1] / 3.0;
      worst = std::max(worst, std::abs(got - partial));
    }
    RenderScene rs(scene_from(slab_scene(ior, 64), dir_ + "/slab.json"), 0);
    const double got = render_frame(rs, 1, 1).image.rgb[1] / 3.0;
    const double closed = (1 - R) / (1 + R);
    const std::string id = "6 slab n=" + std::to_string(ior).substr(0, 3);
    EXPECT_TRUE(check(id, "max |T - partial sum| over max_depth 0..24", worst, Bound::kAtMost, 1e-6));
    EXPECT_TRUE(check(id, "relative error of T vs (1-R)/(1+R), depth 64", std::abs(got - closed) / closed,
                      Bound::kAtMost, 1e-6));
  }
}

TEST_F(GlassTest, SnellsWindowExactFresnelInsideAndLosslessTotalInternalReflectionOutside) {
  // Under a water surface (plane y = 0, glass n = 1.33 below it), looking straight up; black sky,
  // an emissive floor of radiance E at y = -2. Inside Snell's window a pixel sees R(theta) E
  // (the reflection of the floor; the refracted ray escapes to the black sky); outside it, total
  // internal reflection returns exactly E.
  const double n = 1.33, E = 2.0;
  const int size = pick(128, 512);
  const Scene scene = scene_from(R"({
    "camera": {"position": [0, -1, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "vfov_deg": 120},
    "image": {"width": )" + std::to_string(size) + R"(, "height": )" + std::to_string(size) + R"(,
              "spp": 1, "sampler": "center", "max_depth": 4},
    "materials": {"water": {"type": "glass", "ior": 1.33},
                  "floor": {"type": "diffuse", "albedo": 0, "emission": 2}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "water"},
                {"type": "mesh", "file": "floor.obj", "material": "floor"}]})", dir_ + "/window.json");
  RenderScene rs(scene, 0);
  const FrameResult r = render_frame(rs, 32, 2);
  const ScreenPlane sp = screen_plane(scene.camera, size, size);
  const double critical = std::asin(1 / n);
  double worst_inside = 0, worst_inside_abs = 0, worst_outside = 0, first_tir = 10, last_partial = 0;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double u = (x + 0.5) / size, v = (y + 0.5) / size;
      const Vec3d d = normalize(sp.p0 + (sp.p1 - sp.p0) * u + (sp.p2 - sp.p0) * v - sp.eye);
      const double theta = std::acos(d.y);
      const double got = r.image.at(x, y)[0];
      if (got >= E * (1 - 1e-6)) first_tir = std::min(first_tir, theta);
      else last_partial = std::max(last_partial, theta);
      if (std::abs(theta - critical) < 1e-3) continue;  // R has infinite slope at the critical angle
      const double expected = fresnel(d.y, n, 1.0) * E;
      if (theta < critical) {
        // Float bound: the pixel's float direction and the float Fresnel evaluation perturb
        // cos(theta) by a few ulps (4e-7 allowed); near the critical angle R is steep, so the
        // bound scales with |dR/dcos| (taken in double).
        const double h = 1e-8;
        const double slope = std::abs(fresnel(d.y + h, n, 1.0) - fresnel(d.y, n, 1.0)) / h;
        const double err = std::abs(got - expected) / E;
        worst_inside = std::max(worst_inside, err / (1e-6 + slope * 4e-7));
        worst_inside_abs = std::max(worst_inside_abs, err);
      }
      else worst_outside = std::max(worst_outside, std::abs(got - E) / E);
    }
  }
  const double pitch = 2 * std::tan(60 * std::numbers::pi / 180) / size;  // pixel size at the center
  EXPECT_TRUE(check("6 Snell window n=1.33", "max |L - R(theta) E| / E / float bound, inside the window",
                    worst_inside, Bound::kAtMost, 1));
  report("6 Snell window n=1.33", "max |L - R(theta) E| / E inside the window (absolute)", worst_inside_abs, "info");
  EXPECT_TRUE(check("6 Snell window n=1.33", "max |L - E| / E outside (TIR energy loss)", worst_outside,
                    Bound::kAtMost, 1e-6));
  // The window's edge, measured as where lossless TIR starts, against asin(1/n).
  EXPECT_TRUE(check("6 Snell window n=1.33", "|first TIR angle - asin(1/n)| (rad)", std::abs(first_tir - critical),
                    Bound::kAtMost, pitch));
  EXPECT_LT(last_partial, first_tir);
}

TEST_F(GlassTest, IorOneSphereLeavesALitTexturedSceneUnchanged) {
  auto scene = [](bool with_sphere) {
    return std::string(R"({
      "camera": {"position": [0, 1.5, 4], "look_at": [0, 0.5, 0], "vfov_deg": 45},
      "image": {"width": 96, "height": 72, "spp": 1, "sampler": "center", "max_depth": 6},
      "background": [0.3, 0.5, 0.9],
      "lights": [{"type": "point", "position": [-2, 5, 3], "intensity": 60}],
      "materials": {"c": {"type": "diffuse", "albedo": [0.8, 0.2, 0.1], "checker": {"albedo2": 0.9, "scale": 0.5}},
                    "m": {"type": "diffuse", "albedo": [0.2, 0.6, 0.3]},
                    "g": {"type": "glass", "ior": 1.0}},
      "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "c"},
                  {"type": "sphere", "center": [0.8, 0.4, -1.5], "radius": 0.4, "material": "m"})") +
           (with_sphere ? R"(, {"type": "sphere", "center": [0, 0.7, 0], "radius": 0.7, "material": "g"})" : "") +
           "]}";
  };
  RenderScene a(scene_from(scene(false)), 0), b(scene_from(scene(true)), 0);
  const FrameResult ra = render_frame(a, 16, 2), rb = render_frame(b, 16, 2);
  double mean = 0;
  for (float v : ra.image.rgb) mean += v;
  mean /= double(ra.image.rgb.size());
  double worst = 0;
  int off = 0;
  for (size_t i = 0; i < ra.image.rgb.size(); ++i) {
    // Relative to the image mean: relative to the pixel itself it is ill-conditioned on dark pixels.
    const double e = std::abs(double(ra.image.rgb[i]) - double(rb.image.rgb[i])) / mean;
    if (e > 1e-2) ++off;
    else worst = std::max(worst, e);
  }
  // The unbent ray is re-spawned twice (offset origins, renormalized direction): positions move
  // by float rounding only, so values change at float level. A pixel could flip only where the
  // ray passes within rounding of a checker or silhouette edge; the bound allows none.
  EXPECT_TRUE(check("6 ior 1.0 sphere", "values changed by >1% of the mean by the sphere", off, Bound::kAtMost, 0));
  EXPECT_TRUE(check("6 ior 1.0 sphere", "worst change of the other values / image mean", worst, Bound::kAtMost, 1e-5));
}

}  // namespace
}  // namespace tessera::stability

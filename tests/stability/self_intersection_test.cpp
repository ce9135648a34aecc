// SPDX-License-Identifier: Apache-2.0
// Case 2: self-intersection. A light quad 0.01 below a ceiling (as in the Cornell box), a sphere
// of radius 1e6 used as a ground next to a true plane, and curved glass at grazing angles: no
// spurious self-shadowing, checked against closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "render/integrator.h"
#include "render/sphere.h"
#include "scene/animation.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

class SelfIntersection : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("selfint");
    // Ceiling y = 2 (4 x 4, facing down), a 1 x 1 light 0.01 below it (facing down).
    write_text(dir_ + "/ceiling.obj", "v -2 2 -2\nv 2 2 -2\nv 2 2 2\nv -2 2 2\nf 1 2 3\nf 1 3 4\n");
    write_text(dir_ + "/light.obj",
               "v -0.5 1.99 -0.5\nv 0.5 1.99 -0.5\nv 0.5 1.99 0.5\nv -0.5 1.99 0.5\nf 1 2 3\nf 1 3 4\n");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

TEST_F(SelfIntersection, LightQuadJustBelowACeilingIsNotShadowedByIt) {
  // The ceiling lies behind the light: it must block no shadow ray, so the floor renders the
  // same bits with and without it (same samples), and the light itself shows its exact radiance.
  auto scene = [&](bool ceiling, const std::string& camera) {
    return scene_from(R"({
      "camera": )" + camera + R"(,
      "image": {"width": 48, "height": 48, "spp": 4, "max_depth": 2},
      "materials": {"w": {"type": "diffuse", "albedo": 0.8}, "lamp": {"type": "diffuse", "albedo": 0.5, "emission": 5}},
      "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "w"},
                  {"type": "mesh", "file": "light.obj", "material": "lamp"})" +
                      (ceiling ? R"(, {"type": "mesh", "file": "ceiling.obj", "material": "w"})" : "") + "]}",
                      dir_ + "/s.json");
  };
  const std::string floor_cam = R"({"position": [0, 1.5, 0.01], "look_at": [0, 0, 0], "vfov_deg": 90})";
  RenderScene with(scene(true, floor_cam), 0), without(scene(false, floor_cam), 0);
  const FrameResult a = render_frame(with, 16, 2), b = render_frame(without, 16, 2);
  int differ = 0;
  for (size_t i = 0; i < a.image.rgb.size(); ++i) differ += a.image.rgb[i] != b.image.rgb[i];
  EXPECT_TRUE(check("2 light 0.01 below ceiling", "floor values changed by the ceiling", differ, Bound::kAtMost, 0));
  // Looking up at the light (it fills the view): every sample sees emission 5 exactly, never a
  // shadowed or self-lit speck (the lamp is lit only by itself, from behind: nothing).
  RenderScene up(scene(true, R"({"position": [0, 1.5, 0], "look_at": [0, 2, 0], "up": [0, 0, -1], "vfov_deg": 60})"), 0);
  const FrameResult l = render_frame(up, 16, 2);
  int wrong = 0;
  for (float v : l.image.rgb) wrong += v != 5.0f;
  EXPECT_TRUE(check("2 light 0.01 below ceiling", "light pixels != emission", wrong, Bound::kAtMost, 0));
}

TEST_F(SelfIntersection, HugeSphereGroundMatchesAPlaneAndTheAnalyticRadiance) {
  // A ground sphere of radius 1e6 (top at y = 0) and, in a second render, the plane y = 0; a
  // point light at (1, 3, -2). Each pixel's analytic value: rho/pi I cos/r^2 at the surface point
  // (the sphere's curvature is below float resolution here, but the check uses the exact sphere).
  const double R = 1e6, I = 50, rho = 0.6;
  const Vec3d light{1, 3, -2};
  const int w = pick(64, 256), h = pick(48, 192);
  const std::string head = R"({
    "camera": {"position": [0, 1.7, 4], "look_at": [0, 0, -2], "vfov_deg": 60},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) +
                           R"(, "spp": 1, "sampler": "center", "max_depth": 1},
    "lights": [{"type": "point", "position": [1, 3, -2], "intensity": 50}],
    "materials": {"g": {"type": "diffuse", "albedo": 0.6}},
    "objects": [)";
  for (bool sphere : {true, false}) {
    const Scene scene = scene_from(head + (sphere ? R"({"type": "sphere", "center": [0, -1e6, 0], "radius": 1e6, "material": "g"})"
                                                  : R"({"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "g"})") +
                                   "]}");
    RenderScene rs(scene, 0);
    const FrameResult r = render_frame(rs, 16, 2);
    const ScreenPlane sp = screen_plane(scene.camera, w, h);
    int darker = 0, checked = 0;
    double worst = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const Vec3d d = normalize(sp.p0 + (sp.p1 - sp.p0) * ((x + 0.5) / w) + (sp.p2 - sp.p0) * ((y + 0.5) / h) - sp.eye);
        Vec3d p, n;
        if (sphere) {
          double t[2];
          if (intersect_sphere(sp.eye, d, {0, -R, 0}, R, t) == 0 || t[0] < 0) continue;
          p = sp.eye + d * t[0];
          n = normalize(p - Vec3d{0, -R, 0});
        } else {
          if (!(d.y < 0)) continue;
          p = sp.eye + d * (-sp.eye.y / d.y);
          n = {0, 1, 0};
        }
        if (length(p - sp.eye) > 50) continue;  // past 50 units a pixel spans too much radiance change
        const Vec3d to = light - p;
        const double expected = rho / std::numbers::pi * I * dot(n, normalize(to)) / dot(to, to);
        const double got = r.image.at(x, y)[0];
        ++checked;
        darker += got < expected * (1 - 1e-4);
        worst = std::max(worst, std::abs(got - expected) / expected);
      }
    }
    ASSERT_GT(checked, w * h / 3);
    const std::string id = sphere ? "2 ground sphere r=1e6" : "2 ground plane (reference)";
    EXPECT_TRUE(check(id, "pixels darker than analytic (self-shadowing)", darker, Bound::kAtMost, 0));
    EXPECT_TRUE(check(id, "worst relative error vs analytic", worst, Bound::kAtMost, 1e-4));
  }
}

TEST_F(SelfIntersection, GlassSphereAtGrazingAnglesGivesTheExactTruncatedSum) {
  // A glass sphere (n = 1.5, r = 1, 10 away) alone in a uniform background B = 1. A ray with
  // impact parameter b meets every internal hit at the same angle theta_t, so with max_depth D its
  // radiance is exactly 1 - (1 - R_e) R_i^(D-1) (R_e = R_i by reciprocity): the refracted path
  // loses (1 - R_e) R_i^(D-1) when cut at the D-th hit. Spurious self-intersection (a missed or
  // repeated internal hit) breaks this by O(1); rays go up to b = (1 - 1e-7) r.
  // Float bound: render-space points 10 from the eye carry ~1 ulp = 9.5e-7 of position error, so
  // each hit's cosine is off by up to ~2e-6 (r = 1), accumulating over the D hits. Near grazing
  // entry theta_t approaches the critical angle, where R_i is steep, so the bound is
  // 1e-6 + |dL/dcos_i| * 2e-6 * D, with the derivative of the closed form taken in double.
  const double n = 1.5;
  auto fresnel = [&](double cos_i, double n_i, double n_t) {
    const double sin_t = n_i / n_t * std::sqrt(std::max(0.0, 1 - cos_i * cos_i));
    if (sin_t >= 1) return 1.0;
    const double cos_t = std::sqrt(1 - sin_t * sin_t);
    const double rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
    const double rp = (n_t * cos_i - n_i * cos_t) / (n_t * cos_i + n_i * cos_t);
    return 0.5 * (rs * rs + rp * rp);
  };
  for (int D : {3, 8, 64}) {
    RenderScene rs(scene_from(R"({
      "camera": {"position": [0, 0, 0], "look_at": [0, 0, -1]},
      "image": {"max_depth": )" + std::to_string(D) + R"(, "roulette_weight": 0},
      "background": 1,
      "materials": {"g": {"type": "glass", "ior": 1.5}},
      "objects": [{"type": "sphere", "center": [0, 0, -10], "radius": 1, "material": "g"}]})"), 0);
    double worst_ratio = 0, worst_abs = 0;
    int rays = 0;
    const int per_gap = pick(16, 256);
    const PixelSampler sampler(SamplerKind::kCenter, 0, 0, 0, 0, 0, 1);
    for (double gap : {0.5, 0.1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7}) {
      for (int j = 0; j < per_gap; ++j) {
        // The ray from the eye through the point at distance (1 - gap) r from the sphere's axis.
        const double phi = 2 * std::numbers::pi * (j + 0.37) / per_gap;
        const double b = 1 - gap;
        const Vec3f d = Vec3f(normalize(Vec3d{b * std::cos(phi), b * std::sin(phi), -10}));
        // The actual impact parameter of the float direction, in double.
        const Vec3d dd = normalize(Vec3d(d));
        const Vec3d c{0, 0, -10};
        const double bb = length(c - dd * dot(c, dd));
        if (bb >= 1) continue;
        const double cos_e = std::sqrt(1 - bb * bb);
        const double cos_i = std::sqrt(1 - bb * bb / (n * n));  // internal incidence
        const double Re = fresnel(cos_e, 1, n);
        auto closed = [&](double ci) { return 1 - (1 - Re) * std::pow(fresnel(ci, n, 1), D - 1); };
        const double expected = closed(cos_i);
        const double h = 1e-7;
        const double slope = std::abs(closed(cos_i + h) - closed(cos_i)) / h;
        const double bound = 1e-6 + slope * 2e-6 * D;
        RayCounts counts;
        const Rgb L = trace_radiance(rs, {Vec3f(0.0f), d}, sampler, &counts);
        const double err = std::abs(double(L.y) - expected);
        worst_ratio = std::max(worst_ratio, err / bound);
        worst_abs = std::max(worst_abs, err);
        ++rays;
      }
    }
    ASSERT_GT(rays, 8 * per_gap / 2);
    const std::string id = "2 grazing glass D=" + std::to_string(D);
    EXPECT_TRUE(check(id, "max |L - closed form| / float bound, b up to 1-1e-7", worst_ratio, Bound::kAtMost, 1));
    report(id, "max |L - closed form| (absolute)", worst_abs, "info");
  }
}

}  // namespace
}  // namespace tessera::stability

// SPDX-License-Identifier: Apache-2.0
// Case 1: scale invariance. The Whitted showcase translated by 10^k (k = 0..6) and scaled by
// 10^k (k = -3..4), camera and lights moved with it, renders the same image; and an analytic
// scene (a sphere over a plane under a directional light) shows no shadow acne or speckles at
// any of those scales: no pixel darker (or brighter) than its analytic lit value.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <cstdio>
#include <numbers>
#include <string>

#include "render/sphere.h"
#include "scene/animation.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

std::string vec(const Vec3d& v) { return "[" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + "]"; }

// World point p of the showcase, moved by the similarity x -> s x + T.
struct Similarity {
  double s = 1;
  Vec3d T{0, 0, 0};
  Vec3d p(const Vec3d& x) const { return x * s + T; }
};

// scenes/whitted.json, under the similarity: lengths scale by s, point-light intensities by s^2
// (irradiance I/r^2 stays), checker squares by s.
std::string whitted(const Similarity& m, int w, int h, int spp) {
  return R"({
    "camera": {"position": )" + vec(m.p({0, 1.6, 6.5})) + R"(, "look_at": )" + vec(m.p({0, 0.9, 0})) +
         R"(, "vfov_deg": 40},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) + R"(, "spp": )" +
         std::to_string(spp) + R"(, "max_depth": 8, "seed": 1},
    "background": [0.25, 0.45, 0.8],
    "lights": [{"type": "point", "position": )" + vec(m.p({-4, 6, 5})) + R"(, "intensity": )" +
         num(160 * m.s * m.s) + R"(},
               {"type": "point", "position": )" + vec(m.p({5, 7, -1})) + R"(, "intensity": )" +
         vec(Vec3d{90, 85, 75} * (m.s * m.s)) + R"(}],
    "materials": {
      "checker": {"type": "diffuse", "albedo": [0.85, 0.1, 0.08],
                  "checker": {"albedo2": [0.9, 0.85, 0.15], "scale": )" + num(m.s) + R"(}},
      "mirror": {"type": "mirror", "reflectance": 0.92}, "glass": {"type": "glass", "ior": 1.5},
      "matte": {"type": "diffuse", "albedo": [0.2, 0.5, 0.25]}},
    "objects": [
      {"type": "plane", "point": )" + vec(m.p({0, 0, 0})) + R"(, "normal": [0, 1, 0], "material": "checker"},
      {"type": "sphere", "center": )" + vec(m.p({-1.5, 1, -0.8})) + R"(, "radius": )" + num(m.s) +
         R"(, "material": "mirror"},
      {"type": "sphere", "center": )" + vec(m.p({0.55, 0.8, 1.4})) + R"(, "radius": )" + num(0.8 * m.s) +
         R"(, "material": "glass"},
      {"type": "sphere", "center": )" + vec(m.p({2, 0.7, -0.6})) + R"(, "radius": )" + num(0.7 * m.s) +
         R"(, "material": "matte"}]
  })";
}

struct ImageDiff {
  double rel_rmse = 0;         // RMSE over all channels / mean of the reference
  double outlier_fraction = 0; // pixels with a channel off by more than 1% of the reference mean
};

ImageDiff compare(const ImageRGB& a, const ImageRGB& ref) {
  double mean = 0;
  for (float v : ref.rgb) mean += v;
  mean /= double(ref.rgb.size());
  double se = 0;
  size_t outliers = 0;
  for (size_t i = 0; i < ref.pixel_count(); ++i) {
    bool off = false;
    for (int c = 0; c < 3; ++c) {
      const double e = double(a.rgb[3 * i + size_t(c)]) - double(ref.rgb[3 * i + size_t(c)]);
      se += e * e;
      off = off || std::abs(e) > 0.01 * mean;
    }
    outliers += off;
  }
  return {std::sqrt(se / double(ref.rgb.size())) / mean, double(outliers) / double(ref.pixel_count())};
}

// Bounds: camera-relative float render space makes both transformations exact up to float
// rounding of the render-space coordinates (relative 2^-24), so the images agree to a small
// multiple of that; a sample landing within rounding of a silhouette or checker edge may flip,
// which the outlier fraction allows for (0.2% of pixels).
constexpr double kRelRmseBound = 1e-3;
constexpr double kOutlierBound = 2e-3;

TEST(ScaleInvariance, WhittedShowcaseTranslatedBy10PowKRendersTheSameImage) {
  const int w = pick(64, 256), h = pick(36, 144), spp = pick(2, 4);
  RenderScene ref_rs(scene_from(whitted({}, w, h, spp)), 0);
  const FrameResult ref = render_frame(ref_rs, 16, 2);
  for (int k = 0; k <= 6; ++k) {
    const double t = std::pow(10.0, k);
    RenderScene rs(scene_from(whitted({1.0, Vec3d{1, 0.5, -0.75} * t}, w, h, spp)), 0);
    const ImageDiff d = compare(render_frame(rs, 16, 2).image, ref.image);
    const std::string id = "1 translate 1e" + std::to_string(k);
    EXPECT_TRUE(check(id, "relative RMSE vs untranslated", d.rel_rmse, Bound::kAtMost, kRelRmseBound));
    EXPECT_TRUE(check(id, "fraction of pixels off by >1%", d.outlier_fraction, Bound::kAtMost, kOutlierBound));
  }
}

TEST(ScaleInvariance, WhittedShowcaseScaledBy10PowKRendersTheSameImage) {
  const int w = pick(64, 256), h = pick(36, 144), spp = pick(2, 4);
  RenderScene ref_rs(scene_from(whitted({}, w, h, spp)), 0);
  const FrameResult ref = render_frame(ref_rs, 16, 2);
  for (int k = -3; k <= 4; ++k) {
    if (k == 0) continue;
    RenderScene rs(scene_from(whitted({std::pow(10.0, k), {0, 0, 0}}, w, h, spp)), 0);
    const ImageDiff d = compare(render_frame(rs, 16, 2).image, ref.image);
    const std::string id = "1 scale 1e" + std::to_string(k);
    EXPECT_TRUE(check(id, "relative RMSE vs unscaled", d.rel_rmse, Bound::kAtMost, kRelRmseBound));
    EXPECT_TRUE(check(id, "fraction of pixels off by >1%", d.outlier_fraction, Bound::kAtMost, kOutlierBound));
  }
}

// A diffuse sphere hovering over a diffuse plane, one directional light: every pixel's value is
// known in closed form (lit, in the sphere's shadow, or on the sphere's unlit side).
struct AcneResult {
  int classified = 0, darker = 0, brighter = 0;
  double worst_rel = 0;  // worst |error| / radiance of the lit plane
};

AcneResult acne_check(const Similarity& m, int w, int h) {
  const Vec3d eye = m.p({0, 2.5, 5}), target = m.p({0, 0.5, 0}), center = m.p({0.3, 1.2, 0});
  const double radius = 1.0 * m.s;
  const Vec3d light_dir = normalize(Vec3d{0.3, -1, 0.2});
  const double E = 2.0, rho_plane = 0.7, rho_sphere = 0.5;
  const std::string json = R"({
    "camera": {"position": )" + vec(eye) + R"(, "look_at": )" + vec(target) + R"(, "vfov_deg": 50},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) +
                           R"(, "spp": 1, "sampler": "center", "max_depth": 2},
    "lights": [{"type": "directional", "direction": [0.3, -1, 0.2], "irradiance": 2}],
    "materials": {"p": {"type": "diffuse", "albedo": 0.7}, "s": {"type": "diffuse", "albedo": 0.5}},
    "objects": [{"type": "plane", "point": )" + vec(m.p({0, 0, 0})) + R"(, "normal": [0, 1, 0], "material": "p"},
                {"type": "sphere", "center": )" + vec(center) + R"(, "radius": )" + num(radius) +
                           R"(, "material": "s"}]})";
  const Scene scene = scene_from(json);
  RenderScene rs(scene, 0);
  const FrameResult r = render_frame(rs, 16, 2);
  const ScreenPlane sp = screen_plane(scene.camera, w, h);
  const double plane_y = m.p({0, 0, 0}).y;
  AcneResult out;
  constexpr double kMargin = 1e-4;  // relative: skip pixels this close to an analytic boundary
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double u = (x + 0.5) / w, v = (y + 0.5) / h;
      const Vec3d d = normalize(sp.p0 + (sp.p1 - sp.p0) * u + (sp.p2 - sp.p0) * v - sp.eye);
      // Distance of the ray's closest approach to the sphere's center, relative to the radius.
      const Vec3d f = eye - center;
      const double closest = length(f - d * dot(f, d)) / radius;
      if (std::abs(closest - 1) < kMargin) continue;  // silhouette
      double expected;
      double ts[2];
      if (closest < 1 && intersect_sphere(eye, d, center, radius, ts) == 2 && ts[0] > 0) {
        const Vec3d n = normalize(eye + d * ts[0] - center);
        const double c = -dot(n, light_dir);
        if (std::abs(c) < kMargin) continue;  // terminator
        expected = rho_sphere / std::numbers::pi * E * std::max(c, 0.0);
      } else {
        if (!(d.y < 0)) continue;  // sky: black background, nothing to check
        const Vec3d p = eye + d * ((plane_y - eye.y) / d.y);
        const Vec3d g = p - center;
        const double shadow_closest = length(g - (-light_dir) * dot(g, -light_dir)) / radius;
        if (std::abs(shadow_closest - 1) < kMargin) continue;  // shadow edge
        const bool shadowed = shadow_closest < 1 && dot(g, -light_dir) < 0;
        expected = shadowed ? 0.0 : rho_plane / std::numbers::pi * E * -light_dir.y;
      }
      const double got = r.image.at(x, y)[1];
      ++out.classified;
      const double tol = 1e-4 * rho_plane / std::numbers::pi * E;  // of the lit plane's radiance
      if (got < expected - tol) ++out.darker;
      if (got > expected + tol) ++out.brighter;
      // Error relative to the lit plane's radiance: relative to the pixel's own value it is
      // ill-conditioned at the terminator, where the value goes to 0.
      out.worst_rel = std::max(out.worst_rel, std::abs(got - expected) / (rho_plane / std::numbers::pi * E));
    }
  }
  return out;
}

TEST(ScaleInvariance, NoShadowAcneOrSpecklesAtAnyScaleOrOffset) {
  const int w = pick(80, 320), h = pick(60, 240);
  std::vector<std::pair<std::string, Similarity>> cases;
  for (int k = 0; k <= 6; ++k) cases.push_back({"1 acne translate 1e" + std::to_string(k), {1.0, Vec3d{1, 0.5, -0.75} * std::pow(10.0, k)}});
  for (int k = -3; k <= 4; ++k) cases.push_back({"1 acne scale 1e" + std::to_string(k), {std::pow(10.0, k), {0, 0, 0}}});
  for (const auto& [id, m] : cases) {
    const AcneResult a = acne_check(m, w, h);
    ASSERT_GT(a.classified, w * h / 2) << id;
    EXPECT_TRUE(check(id, "pixels darker than analytic (acne)", a.darker, Bound::kAtMost, 0));
    EXPECT_TRUE(check(id, "pixels brighter than analytic (leaks)", a.brighter, Bound::kAtMost, 0));
    EXPECT_TRUE(check(id, "worst error / lit plane radiance", a.worst_rel, Bound::kAtMost, 1e-4));
  }
}

}  // namespace
}  // namespace tessera::stability

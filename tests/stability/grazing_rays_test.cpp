// SPDX-License-Identifier: Apache-2.0
// Case 5: grazing and parallel rays on planes and triangles. Never a NaN, never a hit behind
// the origin: t >= 0, and the returned point lies ahead along the ray (within its error box).
// (lib/render/plane_test.cpp checks intersect_plane's parallel case on its own;
// render_scene_test.cpp one in-plane ray at a cube face.)
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "render/integrator.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

struct GrazingStats {
  size_t rays = 0, hits = 0, nan = 0, behind = 0, off_ray = 0, nonfinite_radiance = 0;
};

// Rays whose direction makes an angle 10^-e (e = 0..12, and exactly 0) with the surface, from
// origins on the surface, just above/below it (an ulp), and 1 above, in every azimuth.
GrazingStats graze(const RenderScene& rs, int per_case, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GrazingStats s;
  const PixelSampler sampler(SamplerKind::kCenter, 0, 0, 0, 0, 0, 1);
  for (int e = -1; e <= 12; ++e) {
    const float elev = e < 0 ? 0.0f : std::pow(10.0f, -float(e));
    for (float height : {0.0f, 0x1p-23f, -0x1p-23f, 1.0f, -1.0f}) {
      for (float sign : {1.0f, -1.0f}) {
        for (int i = 0; i < per_case; ++i) {
          // Render space: the surface is y = -2 (the eye sits 2 above it).
          const Vec3f o{u(rng) * 3, -2.0f + height, u(rng) * 3};
          const float az = u(rng) * 3.14159265f;
          const Vec3f d = normalize(Vec3f{std::cos(az), sign * elev, std::sin(az)});
          Hit h;
          ++s.rays;
          if (rs.intersect({o, d}, {}, &h)) {
            ++s.hits;
            if (!std::isfinite(h.t) || !is_finite(h.p) || !is_finite(h.n) || !is_finite(h.p_err)) ++s.nan;
            if (!(h.t >= 0) || dot(h.p - o, d) < -length(h.p_err) * 4) ++s.behind;
            // The point is where the ray is at t (to float accuracy along a grazing ray).
            if (length(o + d * h.t - h.p) > 1e-5f * (1 + h.t) + 4 * length(h.p_err)) ++s.off_ray;
          }
          RayCounts counts;
          const Rgb L = trace_radiance(rs, {o, d}, sampler, &counts);
          if (!is_finite(L)) ++s.nonfinite_radiance;
        }
      }
    }
  }
  return s;
}

class GrazingRays : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("grazing");
    // The plane y = 0 as two triangles, 200 x 200, facing up.
    write_text(dir_ + "/quad.obj", "v -100 0 -100\nv -100 0 100\nv 100 0 100\nv 100 0 -100\nf 1 2 3\nf 1 3 4\n");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  Scene scene(const std::string& object, const std::string& material) {
    return scene_from(R"({"camera": {"position": [0, 2, 0], "look_at": [0, 0, -1]},
      "image": {"max_depth": 4},
      "background": [0.2, 0.3, 0.4],
      "lights": [{"type": "point", "position": [0.5, 3, 0.5], "intensity": 10},
                 {"type": "directional", "direction": [0, -1, 0.001], "irradiance": 1}],
      "materials": {"m": )" + material + R"(},
      "objects": [)" + object + "]}", dir_ + "/s.json");
  }
  void run(const std::string& name, const std::string& object) {
    for (const auto& [mname, material] :
         std::vector<std::pair<std::string, std::string>>{{"diffuse", R"({"type": "diffuse"})"},
                                                          {"mirror", R"({"type": "mirror"})"},
                                                          {"glass", R"({"type": "glass", "ior": 1.5})"}}) {
      RenderScene rs(scene(object, material), 0);
      const GrazingStats s = graze(rs, pick(40, 400), 11);
      ASSERT_GT(s.hits, s.rays / 10);
      const std::string id = "5 grazing " + name + " " + mname;
      const std::string n = " (" + std::to_string(s.rays) + " rays)";
      EXPECT_TRUE(check(id, "hits with NaN/Inf t, point or normal" + n, double(s.nan), Bound::kAtMost, 0));
      EXPECT_TRUE(check(id, "hits behind the origin (t < 0)" + n, double(s.behind), Bound::kAtMost, 0));
      EXPECT_TRUE(check(id, "hit points off the ray" + n, double(s.off_ray), Bound::kAtMost, 0));
      EXPECT_TRUE(check(id, "non-finite radiance" + n, double(s.nonfinite_radiance), Bound::kAtMost, 0));
    }
  }
  std::string dir_;
};

TEST_F(GrazingRays, Plane) { run("plane", R"({"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"})"); }

TEST_F(GrazingRays, Triangles) { run("triangles", R"({"type": "mesh", "file": "quad.obj", "material": "m"})"); }

}  // namespace
}  // namespace tessera::stability

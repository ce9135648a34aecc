// SPDX-License-Identifier: Apache-2.0
// End-to-end renderer checks against analytic answers and invariants (not against itself).
#include "render/tile_renderer.h"

#include <gtest/gtest.h>

#include <map>

#include <cmath>
#include <numbers>
#include <string>

#include "scene/animation.h"
#include "scene/scene_parser.h"
#include "render/render_scene_internal.h"
#include "render/test_scenes.h"

namespace tessera {
namespace {

using test::whitted_like;

Scene scene_from(const std::string& json) { return parse_scene(json, "test.json"); }

// A Lambertian plane (y = 0) under a point light, seen from above at an angle.
const char* kLitPlane = R"({
  "camera": {"position": [0.3, 2.0, 3.0], "look_at": [0, 0, 0], "vfov_deg": 50},
  "image": {"width": 64, "height": 48, "spp": 1, "max_depth": 4, "sampler": "center"},
  "background": [0, 0, 0],
  "lights": [{"type": "point", "position": [0.5, 1.5, -0.25], "intensity": [160, 80, 40]}],
  "materials": {"m": {"type": "diffuse", "albedo": [0.9, 0.5, 0.25]}},
  "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}]
})";

TEST(Render, LambertianPlaneUnderPointLightMatchesTheAnalyticRadiance) {
  const Scene scene = scene_from(kLitPlane);
  RenderScene rs(scene, 0);
  const FrameResult r = render_frame(rs, 16, 1);
  // Independent computation in double: the pixel-center ray, its plane hit, rho/pi I cos/r^2.
  const ScreenPlane sp = screen_plane(scene.camera, 64, 48);
  const Vec3d light{0.5, 1.5, -0.25};
  const double I[3] = {160, 80, 40}, rho[3] = {0.9, 0.5, 0.25};
  int checked = 0;
  double worst = 0;
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      const double u = (x + 0.5) / 64, v = (y + 0.5) / 48;
      const Vec3d p = sp.p0 + (sp.p1 - sp.p0) * u + (sp.p2 - sp.p0) * v;
      const Vec3d d = normalize(p - sp.eye);
      if (d.y >= 0) continue;  // above the horizon: background
      const double t = -sp.eye.y / d.y;
      const Vec3d hitp = sp.eye + d * t;
      const Vec3d to = light - hitp;
      const double r2 = dot(to, to);
      const double cos_t = to.y / std::sqrt(r2);
      for (int c = 0; c < 3; ++c) {
        const double expected = rho[c] / std::numbers::pi * I[c] * cos_t / r2;
        const double got = r.image.at(x, y)[c];
        const double rel = std::abs(got - expected) / expected;
        worst = std::max(worst, rel);
        ASSERT_LT(rel, 1e-4) << "pixel " << x << "," << y << " channel " << c << " got " << got
                             << " expected " << expected;
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
  std::printf("lit plane: %d pixels, worst relative error %.3g\n", checked, worst);
}

TEST(Render, DirectionalLightIrradianceIsECosTheta) {
  const Scene scene = scene_from(R"({
    "camera": {"position": [0, 3, 0.01], "look_at": [0, 0, 0], "vfov_deg": 30},
    "image": {"width": 8, "height": 8, "spp": 1, "sampler": "center"},
    "lights": [{"type": "directional", "direction": [1, -2, 0.5], "irradiance": 3.0}],
    "materials": {"m": {"type": "diffuse", "albedo": 0.5}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}]
  })");
  RenderScene rs(scene, 0);
  const FrameResult r = render_frame(rs, 8, 1);
  const double cos_t = 2.0 / std::sqrt(1 + 4 + 0.25);
  const double expected = 0.5 / std::numbers::pi * 3.0 * cos_t;
  for (float v : r.image.rgb) EXPECT_NEAR(v, expected, 1e-5 * expected);
}

// `roulette`: the scene's roulette_weight (0: every branch of the tree traced).
std::string invisible_sphere_scene(const std::string& material, double roulette = 0.01, int spp = 4) {
  return R"({
    "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "vfov_deg": 40},
    "image": {"width": 48, "height": 48, "spp": )" + std::to_string(spp) + R"(, "max_depth": 64,
              "roulette_weight": )" + std::to_string(roulette) + R"(},
    "background": [0.3, 0.6, 0.9],
    "materials": {"m": )" + material + R"(},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}]
  })";
}

void expect_all_background(const FrameResult& r, const Rgb& bg) {
  for (size_t i = 0; i < r.image.pixel_count(); ++i) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_NEAR(r.image.rgb[3 * i + size_t(c)], bg[c], 1e-5 * bg[c]) << "pixel " << i;
    }
  }
}

TEST(Render, PerfectMirrorInUniformBackgroundIsInvisible) {
  RenderScene rs(scene_from(invisible_sphere_scene(R"({"type": "mirror", "reflectance": 1})")), 0);
  expect_all_background(render_frame(rs, 16, 2), {0.3f, 0.6f, 0.9f});
}

TEST(Render, GlassOfIndexOneInUniformBackgroundIsInvisible) {
  RenderScene rs(scene_from(invisible_sphere_scene(R"({"type": "glass", "ior": 1.0})")), 0);
  expect_all_background(render_frame(rs, 16, 2), {0.3f, 0.6f, 0.9f});
}

TEST(Render, GlassSphereConservesEnergyInUniformBackground) {
  // Any ior: reflection + refraction partition energy exactly (R + T = 1), and every path
  // escapes to the uniform background, so the sphere vanishes up to the tail cut at max_depth
  // (largest at grazing entry, where the internal reflectance approaches 1). Every branch is
  // traced: this is the tree's arithmetic, pixel by pixel (the roulette's average is the next test).
  RenderScene rs(scene_from(invisible_sphere_scene(R"({"type": "glass", "ior": 1.5})", 0.0)), 0);
  const FrameResult r = render_frame(rs, 16, 2);
  double worst = 0, sum = 0;
  for (size_t i = 0; i < r.image.pixel_count(); ++i) {
    const double rel = std::abs(r.image.rgb[3 * i + 1] - 0.6) / 0.6;
    worst = std::max(worst, rel);
    sum += rel;
  }
  std::printf("glass sphere energy: worst pixel %.3g, mean %.3g relative loss\n", worst,
              sum / double(r.image.pixel_count()));
  EXPECT_LT(worst, 2e-3);
  EXPECT_LT(sum / double(r.image.pixel_count()), 1e-5);
}

TEST(Render, RouletteCutsTheGlassTreeAndKeepsItsAverage) {
  // The same invisible glass sphere with Russian roulette below a path weight of 0.01 (the
  // default): single pixels now scatter around the background, but their average must not move
  // (the roulette is unbiased: a kept branch counts 1/p times), while most of the internal
  // reflections are no longer traced.
  const std::string glass = R"({"type": "glass", "ior": 1.5})";
  RenderScene all(scene_from(invisible_sphere_scene(glass, 0.0, 64)), 0);
  RenderScene cut(scene_from(invisible_sphere_scene(glass, 0.01, 64)), 0);
  const FrameResult a = render_frame(all, 16, 2), r = render_frame(cut, 16, 2);
  const double n = double(r.image.pixel_count());
  double mean = 0, worst = 0;
  for (size_t i = 0; i < r.image.pixel_count(); ++i) {
    const double d = r.image.rgb[3 * i + 1] - 0.6;
    mean += d / n;
    worst = std::max(worst, std::abs(d));
  }
  double var = 0;
  for (size_t i = 0; i < r.image.pixel_count(); ++i) var += std::pow(r.image.rgb[3 * i + 1] - 0.6 - mean, 2) / (n - 1);
  const uint64_t traced = r.rays.secondary, every = a.rays.secondary;
  std::printf("roulette: %llu of %llu secondary rays, mean deviation %.3g (4 sigma %.3g), worst pixel %.3g\n",
              (unsigned long long)traced, (unsigned long long)every, mean, 4 * std::sqrt(var / n), worst);
  EXPECT_LT(double(traced), 0.6 * double(every));
  EXPECT_GT(worst, 1e-4);  // the roulette did play: some pixel left the background
  // The average over 2304 independent pixels: within 4 standard errors, plus the tree's own
  // truncation at max_depth (under 1e-5 relative, the previous test).
  EXPECT_LT(std::abs(mean), 4 * std::sqrt(var / n) + 0.6e-5);
}

TEST(Render, NoLightsAndBlackBackgroundIsExactlyBlack) {
  RenderScene rs(scene_from(R"({
    "camera": {"position": [0, 1, 4], "look_at": [0, 0, 0]},
    "image": {"width": 16, "height": 16, "spp": 2},
    "materials": {"m": {"type": "diffuse"}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}]
  })"), 0);
  const FrameResult r = render_frame(rs, 8, 1);
  for (float v : r.image.rgb) EXPECT_EQ(v, 0.0f);
  EXPECT_EQ(r.estimated_rmse(), 0.0);
}

TEST(Render, BitIdenticalForAnyTileSizeAndThreadCount) {
  RenderScene rs(scene_from(whitted_like(97, 61, 3)), 0);  // odd sizes: ragged edge tiles
  const FrameResult ref = render_frame(rs, 16, 1);
  for (int tile : {8, 64, 1, 13}) {
    for (int threads : {1, 2}) {
      const FrameResult r = render_frame(rs, tile, threads);
      ASSERT_EQ(r.image.rgb, ref.image.rgb) << "tile " << tile << " threads " << threads;
      ASSERT_EQ(r.variance, ref.variance) << "tile " << tile << " threads " << threads;
      EXPECT_EQ(r.rays.total(), ref.rays.total());
    }
  }
}

TEST(Render, TilesRenderedTwiceOrInAnyOrderAreIdentical) {
  const Scene scene = scene_from(whitted_like(40, 30, 2));
  RenderScene a(scene, 0);
  RenderScene b(scene, 0);  // a separately built Embree scene (as on another worker)
  const TileRect rect{8, 5, 17, 11};
  const TileResult t1 = render_tile(a, rect);
  render_tile(a, {0, 0, 40, 30});
  const TileResult t2 = render_tile(b, rect);
  EXPECT_EQ(t1.rgb, t2.rgb);
  EXPECT_EQ(t1.variance, t2.variance);
  // And the tile equals the same pixels of a whole-frame render.
  const FrameResult full = render_frame(a, 32, 2);
  for (int y = 0; y < rect.height; ++y) {
    for (int x = 0; x < rect.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(t1.rgb[3 * size_t(y * rect.width + x) + size_t(c)], full.image.at(rect.x0 + x, rect.y0 + y)[c]);
      }
    }
  }
}

TEST(Render, SeedAndFrameChangeTheNoiseButNotTheMean) {
  Scene s1 = scene_from(whitted_like(32, 24, 4));
  Scene s2 = s1;
  s2.image.seed = 99;
  RenderScene a(s1, 0), b(s2, 0);
  const FrameResult ra = render_frame(a), rb = render_frame(b);
  EXPECT_NE(ra.image.rgb, rb.image.rgb);
  double ma = 0, mb = 0;
  for (size_t i = 0; i < ra.image.rgb.size(); ++i) {
    ma += ra.image.rgb[i];
    mb += rb.image.rgb[i];
  }
  EXPECT_NEAR(ma / mb, 1.0, 0.02);
}

TEST(Render, EstimatedErrorTracksTheTrueErrorAndFallsWithSpp) {
  // The per-pixel variance estimate must be honest: compare the estimated RMSE with the
  // measured RMSE against a high-spp reference, at two sample counts.
  auto render = [](int spp, uint64_t seed) {
    Scene s = parse_scene(whitted_like(48, 32, spp), "test.json");
    s.image.seed = seed;
    s.image.sampler = SamplerKind::kIndependent;  // the estimate assumes independent samples
    RenderScene rs(s, 0);
    return render_frame(rs, 16, 2);
  };
  const FrameResult ref = render(1024, 7);
  double prev_true = 1e30;
  for (int spp : {4, 32}) {
    const FrameResult r = render(spp, 1);
    double se = 0;
    for (size_t i = 0; i < r.image.rgb.size(); ++i) {
      const double e = double(r.image.rgb[i]) - double(ref.image.rgb[i]);
      se += e * e;
    }
    const double true_rmse = std::sqrt(se / double(r.image.rgb.size()));
    const double est = r.estimated_rmse();
    std::printf("spp %d: true RMSE %.4g, estimated %.4g\n", spp, true_rmse, est);
    EXPECT_GT(est / true_rmse, 0.7);
    EXPECT_LT(est / true_rmse, 1.4);
    EXPECT_LT(true_rmse, prev_true);
    prev_true = true_rmse;
  }
}

// A block-bound render (block_rmse) of the Whitted-like scene: easy background blocks stop at
// min_spp, edges and glass take more.
Scene adaptive_scene(int w, int h, double target, int min_spp, int max_spp) {
  Scene s = scene_from(whitted_like(w, h, 16));
  s.image.block_rmse = target;
  s.image.min_spp = min_spp;
  s.image.max_spp = max_spp;
  return s;
}

TEST(AdaptiveRender, BitIdenticalForAnyTileSizeThreadCountAndRepetition) {
  // Odd sizes: blocks clipped at the image's edges; tile sizes that are not multiples of the
  // block size render blocks shared by several tiles.
  RenderScene rs(adaptive_scene(75, 53, 0.02, 8, 128), 0);
  const FrameResult ref = render_frame(rs, 16, 1);
  uint32_t lo = ~0u, hi = 0;
  for (uint32_t n : ref.spp) {
    lo = std::min(lo, n);
    hi = std::max(hi, n);
  }
  ASSERT_EQ(lo, 8u);  // some blocks stop at once...
  ASSERT_GT(hi, 8u);  // ...and others do not: the test exercises the decisions
  for (int tile : {8, 13, 64, 5}) {
    for (int threads : {1, 2}) {
      const FrameResult r = render_frame(rs, tile, threads);
      ASSERT_EQ(r.image.rgb, ref.image.rgb) << "tile " << tile << " threads " << threads;
      ASSERT_EQ(r.variance, ref.variance) << "tile " << tile << " threads " << threads;
      ASSERT_EQ(r.spp, ref.spp) << "tile " << tile << " threads " << threads;
    }
  }
  RenderScene again(adaptive_scene(75, 53, 0.02, 8, 128), 0);  // another Embree scene, as on another worker
  const TileResult t = render_tile(again, {13, 7, 29, 31});
  for (int y = 0; y < 31; ++y) {
    for (int x = 0; x < 29; ++x) {
      ASSERT_EQ(t.spp[size_t(y * 29 + x)], ref.spp[size_t((7 + y) * 75 + 13 + x)]);
      for (int c = 0; c < 3; ++c) ASSERT_EQ(t.rgb[3 * size_t(y * 29 + x) + size_t(c)], ref.image.at(13 + x, 7 + y)[c]);
    }
  }
}

TEST(AdaptiveRender, APixelThatStoppedAtNSamplesEqualsTheUniformNSppRender) {
  // The sampler is progressive and the sums run in sample order, so an adaptive pixel is the
  // uniform render at its own sample count, bit for bit.
  RenderScene rs(adaptive_scene(48, 32, 0.008, 8, 64), 0);
  const FrameResult a = render_frame(rs, 32, 2);
  std::map<uint32_t, FrameResult> uniform;
  size_t checked = 0;
  for (size_t i = 0; i < a.spp.size(); ++i) {
    const uint32_t n = a.spp[i];
    if (!uniform.count(n)) {
      Scene s = scene_from(whitted_like(48, 32, int(n)));
      RenderScene u(s, 0);
      uniform.emplace(n, render_frame(u, 32, 2));
    }
    const FrameResult& u = uniform.at(n);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(a.image.rgb[3 * i + size_t(c)], u.image.rgb[3 * i + size_t(c)]) << i;
    ASSERT_EQ(a.variance[i], u.variance[i]) << i;
    ++checked;
  }
  EXPECT_GE(uniform.size(), 2u);  // several stopping points were compared
  EXPECT_EQ(checked, a.spp.size());
}

TEST(AdaptiveRender, EveryBlockMeetsTheTargetOrStopsAtMaxSpp) {
  const double target = 0.004;
  Scene s = adaptive_scene(64, 40, target, 8, 32);  // max_spp low: some blocks cannot make it
  RenderScene rs(s, 0);
  const FrameResult r = render_frame(rs, 32, 2);
  const SampleSummary sum = r.summary();
  int64_t at_max_above = 0, below_max_above = 0;
  for (int by = 0; by < 40; by += kAdaptiveBlock) {
    for (int bx = 0; bx < 64; bx += kAdaptiveBlock) {
      double mse = 0;
      const uint32_t n = r.spp[size_t(by * 64 + bx)];
      for (int y = by; y < by + kAdaptiveBlock; ++y) {
        for (int x = bx; x < bx + kAdaptiveBlock; ++x) {
          mse += r.variance[size_t(y * 64 + x)] / double(kAdaptiveBlock * kAdaptiveBlock);
          ASSERT_EQ(r.spp[size_t(y * 64 + x)], n) << "a block's pixels share their sample count";
        }
      }
      if (mse > target * target) (n == 32 ? at_max_above : below_max_above)++;
    }
  }
  EXPECT_EQ(below_max_above, 0) << "a block stopped above the target before max_spp";
  EXPECT_GT(at_max_above, 0) << "max_spp 32 was expected to stop some blocks above the target";
  EXPECT_EQ(sum.unconverged_blocks, at_max_above);
  EXPECT_EQ(sum.max_spp, 32u);
  EXPECT_EQ(sum.min_spp, 8u);
}

TEST(AdaptiveRender, NextSampleCountIsBoundedAndWholePackets) {
  EXPECT_EQ(next_sample_count(16, 4.0, 1.0, 1024), 32u);    // far off: at most doubling
  EXPECT_EQ(next_sample_count(16, 1.1, 1.0, 1024), 24u);    // close: one more packet
  EXPECT_EQ(next_sample_count(64, 1.5, 1.0, 1024), 96u);    // 1/spp prediction
  EXPECT_EQ(next_sample_count(600, 4.0, 1.0, 1000), 1000u); // capped at max_spp
  EXPECT_EQ(next_sample_count(20, 1.5, 1.0, 1024) % 8, 0u);
}

}  // namespace
}  // namespace tessera

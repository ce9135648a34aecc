// SPDX-License-Identifier: Apache-2.0
// The lattice sampler against independent references: on smooth shading its corner means beat
// jittered samples by far at equal samples, a sub-pixel feature the lattice misses shows up in its
// audited estimate, its edge pixels are the default sampler's bit for bit, and its frames do not
// depend on thread count or tile size.
#include "render/lattice_sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "render/render_scene_internal.h"
#include "render/test_scenes.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

double rmse_against(const ImageRGB& a, const ImageRGB& b) {
  double se = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) se += (double(a.rgb[i]) - double(b.rgb[i])) * (double(a.rgb[i]) - double(b.rgb[i]));
  return std::sqrt(se / double(a.rgb.size()));
}

// A diffuse wall filling the view, lit by a point light off to one side: shading that varies
// across the frame by a factor of several but smoothly everywhere.
std::string smooth_wall_scene(int w, int h, int spp) {
  return R"({
    "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "vfov_deg": 40},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) +
         R"(, "spp": )" + std::to_string(spp) + R"(, "max_depth": 2, "seed": 1},
    "background": [0, 0, 0],
    "lights": [{"type": "point", "position": [-3, 1, 2], "intensity": 30}],
    "materials": {"d": {"type": "diffuse", "albedo": [0.8, 0.7, 0.6]}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "d"}]
  })";
}

// A grey wall with a scatter of bright spheres a fifth of a pixel across (400 of them on a
// 64 x 40 frame): features the corners mostly fall between.
std::string dust_scene(int w, int h, int spp, uint64_t seed) {
  std::string objects = R"({"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "grey"})";
  // The frame is 2 * 4.5 * tan(20 deg) = 3.28 units tall at z = 0.5: a pixel is 3.28 / h across.
  const double height = 3.28, width = height * double(w) / double(h), pixel = height / double(h);
  for (int i = 0; i < 400; ++i) {
    // Spread over the frame by the golden ratio's low-discrepancy sequence.
    const double u = std::fmod(0.5 + 0.6180339887 * i, 1.0), v = (i + 0.5) / 400.0;
    objects += R"(, {"type": "sphere", "center": [)" + std::to_string((u - 0.5) * 0.95 * width) + ", " +
               std::to_string((v - 0.5) * 0.95 * height) + R"(, 0.5], "radius": )" + std::to_string(0.1 * pixel) +
               R"(, "material": "white"})";
  }
  return R"({
    "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "vfov_deg": 40},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) +
         R"(, "spp": )" + std::to_string(spp) + R"(, "max_depth": 2, "seed": )" + std::to_string(seed) + R"(},
    "background": [0, 0, 0],
    "lights": [{"type": "directional", "direction": [0, 0, -1], "irradiance": 3}],
    "materials": {"grey": {"type": "diffuse", "albedo": [0.2, 0.2, 0.2]},
                  "white": {"type": "diffuse", "albedo": [1, 1, 1]}},
    "objects": [)" + objects + R"(]
  })";
}

FrameResult render_with(const std::string& json, SamplerKind sampler, double target, int threads = 2, int tile = 32,
                   int min_spp = 0) {
  Scene s = parse_scene(json, "test.json");
  s.image.sampler = sampler;
  s.image.target_rmse = target;
  s.image.min_spp = min_spp;
  RenderScene rs(s, 0);
  return render_frame(rs, tile, threads);
}

TEST(LatticeSampler, CurvatureIsTheLargestSecondDifference) {
  // A 3 x 2 pixel lattice (4 x 3 corners), every channel L = x^2 + 3 y: second differences 2
  // along x, 0 along y, whatever the pixel.
  CornerLattice c;
  for (int y = 0; y <= 2; ++y) {
    for (int x = 0; x <= 3; ++x) c.push_back(Rgb(float(x * x + 3 * y)));
  }
  for (int py = 0; py < 2; ++py) {
    for (int px = 0; px < 3; ++px) EXPECT_FLOAT_EQ(corner_curvature(c, 3, 2, px, py), 2.0f);
  }
  // A linear field has none; a bump of 1 at corner (1, 1) shows as 2 at the four pixels around
  // it and as 1 in the pixel whose corner (2, 1) has it as a neighbour.
  for (int y = 0; y <= 2; ++y) {
    for (int x = 0; x <= 3; ++x) c[size_t(y * 4 + x)] = Rgb(float(x + 3 * y));
  }
  EXPECT_FLOAT_EQ(corner_curvature(c, 3, 2, 2, 1), 0.0f);
  c[1 * 4 + 1] = c[1 * 4 + 1] + Rgb(1.0f);
  EXPECT_FLOAT_EQ(corner_curvature(c, 3, 2, 0, 0), 2.0f);
  EXPECT_FLOAT_EQ(corner_curvature(c, 3, 2, 1, 1), 2.0f);
  EXPECT_FLOAT_EQ(corner_curvature(c, 3, 2, 2, 1), 1.0f);
  // A step of 1 between corner columns 2 and 3 of a 6 x 4 pixel lattice: only the pixels it
  // crosses see it, not their neighbours, whose own corners agree.
  CornerLattice step;
  for (int y = 0; y <= 4; ++y) {
    for (int x = 0; x <= 6; ++x) step.push_back(Rgb(x >= 3 ? 1.0f : 0.0f));
  }
  for (int py = 0; py < 4; ++py) {
    for (int px = 0; px < 6; ++px) EXPECT_FLOAT_EQ(corner_curvature(step, 6, 4, px, py), px == 2 ? 1.0f : 0.0f) << px;
  }
}

// The classification's row-at-a-time curvature is corner_curvature's, bit for bit, on a lattice of
// random radiance (border pixels included) and on lattices too narrow for a second difference.
TEST(LatticeSampler, CurvatureByRowsIsCornerCurvature) {
  uint64_t state = 7;
  for (auto [w, h] : {std::pair{13, 9}, std::pair{2, 5}, std::pair{1, 4}, std::pair{6, 1}}) {
    CornerLattice c;
    for (int i = 0; i < (w + 1) * (h + 1); ++i) {
      Rgb v;
      for (int k = 0; k < 3; ++k) v[k] = to_unit_float(uint32_t(state = mix64(state)));
      c.push_back(v);
    }
    std::vector<float> rows(size_t(w) * size_t(h), -1.0f);
    corner_curvature_rows(c, w, h, 0, (h + 1) / 2, rows.data());
    corner_curvature_rows(c, w, h, (h + 1) / 2, h, rows.data());
    for (int py = 0; py < h; ++py) {
      for (int px = 0; px < w; ++px) {
        const float want = corner_curvature(c, w, h, px, py);
        const float got = rows[size_t(py) * size_t(w) + size_t(px)];
        ASSERT_TRUE(got == want) << w << "x" << h << " pixel " << px << "," << py << ": " << got << " against " << want;
      }
    }
  }
}

TEST(LatticeSampler, SmoothShadingFarBelowJitteredSamplesAtEqualSamples) {
  const int w = 64, h = 40;
  const ImageRGB ref = render_with(smooth_wall_scene(w, h, 256), SamplerKind::kSobol, 0).image;
  const FrameResult lattice = render_with(smooth_wall_scene(w, h, 1), SamplerKind::kLattice, 0.01);
  const SampleSummary s = lattice.summary();
  // Every block smooth: one lattice ray a pixel (plus the audits), no pixel taking streams.
  EXPECT_LE(s.max_spp, 3u);
  EXPECT_LT(double(lattice.rays.camera) / double(w * h), 1.25);
  // Jittered samples at the same count, 1 spp and 2 spp (the lattice traces (w + 1)(h + 1)
  // corners, and two audit samples in about a tenth of the pixels).
  const double e_lattice = rmse_against(lattice.image, ref);
  const double e1 = rmse_against(render_with(smooth_wall_scene(w, h, 1), SamplerKind::kSobol, 0).image, ref);
  const double e2 = rmse_against(render_with(smooth_wall_scene(w, h, 2), SamplerKind::kSobol, 0).image, ref);
  std::printf("smooth wall: lattice %.3g (mean spp %.2f), sobol 1 spp %.3g, 2 spp %.3g\n", e_lattice, s.mean_spp, e1,
              e2);
  // A tenth of two jittered samples' error (measured: a twentieth), with fewer rays.
  EXPECT_LT(e_lattice, 0.1 * e2);
  EXPECT_LT(e_lattice, 0.2 * e1);
  EXPECT_LT(e_lattice, 0.01) << "the target";
  // Its estimate is honest (the audits estimate each smooth pixel's squared error without bias).
  EXPECT_GE(s.estimated_rmse, 0.8 * e_lattice);
}

TEST(LatticeSampler, ASubPixelFeatureTheLatticeMissesShowsUpInTheEstimate) {
  const int w = 64, h = 40;
  const ImageRGB ref = render_with(dust_scene(w, h, 256, 1), SamplerKind::kSobol, 0).image;
  double estimated = 0, measured = 0;
  const int seeds = 8;
  for (uint64_t seed = 1; seed <= uint64_t(seeds); ++seed) {
    const FrameResult r = render_with(dust_scene(w, h, 1, seed), SamplerKind::kLattice, 0.05);
    const double e = rmse_against(r.image, ref), est = r.summary().estimated_rmse;
    std::printf("dust, seed %d: estimated %.4g, measured %.4g, mean spp %.2f\n", int(seed), est, e, r.summary().mean_spp);
    estimated += est * est;
    measured += e * e;
  }
  // The spheres are missed (a frame mostly at the lattice's one sample) and cost real error...
  EXPECT_GT(std::sqrt(measured / seeds), 0.005);
  // ...which the audits see: on average over seeds the estimate comes to it.
  EXPECT_GE(std::sqrt(estimated / seeds), 0.8 * std::sqrt(measured / seeds));
}

TEST(LatticeSampler, EdgePixelsAreTheDefaultSamplersBitForBit) {
  const int w = 48, h = 32;
  // Edge pixels from 4 samples: the smooth pixels are those at 1 or 3 (with an audit).
  const FrameResult a = render_with(test::whitted_like(w, h, 1), SamplerKind::kLattice, 0.01, 2, 32, 4);
  std::map<uint32_t, FrameResult> uniform;
  int edge_pixels = 0;
  for (size_t i = 0; i < a.spp.size(); ++i) {
    const uint32_t n = a.spp[i];
    if (n <= 3) continue;
    ++edge_pixels;
    if (!uniform.count(n)) uniform.emplace(n, render_with(test::whitted_like(w, h, int(n)), SamplerKind::kSobol, 0));
    const FrameResult& u = uniform.at(n);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(a.image.rgb[3 * i + size_t(c)], u.image.rgb[3 * i + size_t(c)]) << i;
    ASSERT_EQ(a.variance[i], u.variance[i]) << i;
  }
  EXPECT_GT(edge_pixels, 50);
}

// The cost breakdown accounts for every camera ray and every pixel.
TEST(LatticeSampler, CostAccountsForEveryCameraRayAndPixel) {
  const int w = 75, h = 53;
  const FrameResult r = render_with(test::whitted_like(w, h, 1), SamplerKind::kLattice, 0.008, 2, 32, 4);
  const LatticeCost& c = r.lattice;
  EXPECT_EQ(c.corner_rays, uint64_t((w + 1) * (h + 1)));
  EXPECT_EQ(c.corner_rays + c.audit_rays + c.edge_rays, r.rays.camera);
  EXPECT_EQ(c.audit_rays, uint64_t(2 * c.audited_pixels));
  EXPECT_EQ(c.smooth_pixels + c.edge_pixels, int64_t(w * h));
  EXPECT_GT(c.smooth_pixels, 0);
  EXPECT_GT(c.edge_pixels, 0);
  EXPECT_LE(c.audited_pixels, c.smooth_pixels);
  int64_t smooth = 0, audited = 0;
  for (uint32_t n : r.spp) smooth += n <= 3, audited += n == 3;  // edge pixels take at least 4 (min_spp)
  EXPECT_EQ(c.smooth_pixels, smooth);
  EXPECT_EQ(c.audited_pixels, audited);
  EXPECT_GE(c.passes, 1);
  EXPECT_GT(c.corner_seconds, 0.0);
  EXPECT_GT(c.pass_seconds, 0.0);
  // A render with another sampler leaves it zero.
  EXPECT_EQ(render_with(test::whitted_like(w, h, 1), SamplerKind::kSobol, 0.008, 2, 32).lattice.corner_rays, 0u);
}

TEST(LatticeSampler, BitIdenticalForAnyThreadCountAndTileSize) {
  const FrameResult ref = render_with(test::whitted_like(75, 53, 1), SamplerKind::kLattice, 0.008, 1, 32);
  for (auto [threads, tile] : {std::pair{2, 16}, std::pair{3, 7}}) {
    const FrameResult r = render_with(test::whitted_like(75, 53, 1), SamplerKind::kLattice, 0.008, threads, tile);
    ASSERT_EQ(r.image.rgb, ref.image.rgb) << threads;
    ASSERT_EQ(r.variance, ref.variance) << threads;
    ASSERT_EQ(r.spp, ref.spp) << threads;
  }
}

TEST(LatticeSampler, RefusedWithoutAFrameTarget) {
  Scene s = parse_scene(test::whitted_like(8, 8, 4), "test.json");
  ImageOverrides o;
  o.sampler = SamplerKind::kLattice;
  try {
    apply_overrides(s, o);
    FAIL() << "a uniform lattice render was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("--sampler lattice"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--target-rmse"), std::string::npos) << e.what();
  }
  o.target_rmse = 0.01;
  EXPECT_NO_THROW(apply_overrides(s, o));
}

}  // namespace
}  // namespace tessera

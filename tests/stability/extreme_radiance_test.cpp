// SPDX-License-Identifier: Apache-2.0
// Case 8: extreme radiance. Point lights of 1e-6, 160 (the showcase's bright light) and 1e6, and
// the format's largest 1e20, stay exact in float against the analytic rho/pi I cos/r^2; emitters
// of 1e-6 and 1e6 are seen exactly; an irradiance that overflows float never reaches a pixel as
// Inf (it is counted); half-float output clamps to 65504 and warns.
#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "image/exr_io.h"
#include "scene/animation.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

std::string lit_plane(double intensity, double light_height, int size) {
  return R"({"camera": {"position": [0.3, 2, 3], "look_at": [0, 0, 0], "vfov_deg": 50},
    "image": {"width": )" + std::to_string(size) + R"(, "height": )" + std::to_string(size) +
         R"(, "spp": 1, "sampler": "center", "max_depth": 1},
    "lights": [{"type": "point", "position": [0.5, )" + num(light_height) + R"(, -0.25], "intensity": )" +
         num(intensity) + R"(}],
    "materials": {"m": {"type": "diffuse", "albedo": 0.9}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}]})";
}

TEST(ExtremeRadiance, PointLightsFrom1eMinus6To1e20StayExactInFloat) {
  const int size = pick(32, 128);
  for (double I : {1e-6, 160.0, 1e6, 1e20}) {
    const Scene scene = scene_from(lit_plane(I, 1.5, size));
    RenderScene rs(scene, 0);
    const FrameResult r = render_frame(rs, 16, 2);
    const ScreenPlane sp = screen_plane(scene.camera, size, size);
    double worst = 0;
    int checked = 0;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        const Vec3d d = normalize(sp.p0 + (sp.p1 - sp.p0) * ((x + 0.5) / size) + (sp.p2 - sp.p0) * ((y + 0.5) / size) - sp.eye);
        if (d.y >= 0) continue;
        const Vec3d p = sp.eye + d * (-sp.eye.y / d.y);
        const Vec3d to = Vec3d{0.5, 1.5, -0.25} - p;
        const double expected = 0.9 / std::numbers::pi * I * to.y / std::sqrt(dot(to, to)) / dot(to, to);
        worst = std::max(worst, std::abs(r.image.at(x, y)[1] - expected) / expected);
        ++checked;
      }
    }
    ASSERT_GT(checked, size * size / 2);
    char id[64];
    std::snprintf(id, sizeof id, "8 point light I=%g", I);
    EXPECT_TRUE(check(id, "worst relative error vs rho/pi I cos/r^2", worst, Bound::kAtMost, 1e-5));
  }
}

TEST(ExtremeRadiance, EmittersOf1eMinus6And1e6AreSeenExactly) {
  const std::string dir = make_temp_dir("radiance");
  write_text(dir + "/quad.obj", "v -5 -5 -1\nv 5 -5 -1\nv 5 5 -1\nv -5 5 -1\nf 1 2 3\nf 1 3 4\n");
  for (double E : {1e-6, 1e6}) {
    RenderScene rs(scene_from(R"({"camera": {"position": [0, 0, 0], "look_at": [0, 0, -1], "vfov_deg": 60},
      "image": {"width": 16, "height": 16, "spp": 4},
      "materials": {"e": {"type": "diffuse", "albedo": 0, "emission": )" + num(E) + R"(}},
      "objects": [{"type": "mesh", "file": "quad.obj", "material": "e"}]})", dir + "/s.json"), 0);
    const FrameResult r = render_frame(rs, 16, 1);
    double worst = 0;
    for (float v : r.image.rgb) worst = std::max(worst, std::abs(v - float(E)) / E);
    char id[64];
    std::snprintf(id, sizeof id, "8 emitter L=%g", E);
    EXPECT_TRUE(check(id, "worst relative error of seen radiance", worst, Bound::kAtMost, 0));
  }
  std::filesystem::remove_all(dir);
}

TEST(ExtremeRadiance, OverflowingIrradianceNeverReachesAPixelAsInf) {
  // I = 1e20 at 1e-12 above the plane, seen from 2e-12 above it: I / r^2 ~ 1e44 > FLT_MAX.
  // Such samples are dropped to 0 and counted (RayCounts::nonfinite_samples; the CLI warns),
  // never written as Inf or NaN.
  RenderScene rs(scene_from(R"({"camera": {"position": [0, 2e-12, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "vfov_deg": 90},
    "image": {"width": 16, "height": 16, "spp": 1, "sampler": "center", "max_depth": 1},
    "lights": [{"type": "point", "position": [0.3e-12, 1e-12, 0], "intensity": 1e20}],
    "materials": {"m": {"type": "diffuse", "albedo": 0.9}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}]})"), 0);
  const FrameResult r = render_frame(rs, 16, 1);
  int nonfinite = 0;
  for (float v : r.image.rgb) nonfinite += !std::isfinite(v);
  for (float v : r.variance) nonfinite += !std::isfinite(v);
  EXPECT_TRUE(check("8 overflow I=1e20 at 1e-12", "non-finite pixel or variance values", nonfinite, Bound::kAtMost, 0));
  // The overflow is reported, not hidden.
  EXPECT_TRUE(check("8 overflow I=1e20 at 1e-12", "overflowing samples counted", double(r.rays.nonfinite_samples),
                    Bound::kAtLeast, 1));
}

TEST(ExtremeRadiance, HalfFloatOutputClampsAndWarns) {
  RenderScene rs(scene_from(lit_plane(1e6, 1.5, 16)), 0);
  const FrameResult r = render_frame(rs, 16, 1);
  float peak = 0;
  for (float v : r.image.rgb) peak = std::max(peak, v);
  ASSERT_GT(peak, 65504.0f);  // the render itself holds the true values, in float
  auto sink = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(8);
  spdlog::default_logger()->sinks().push_back(sink);
  const auto path = (std::filesystem::temp_directory_path() / "tessera_stability_half.exr").string();
  write_exr(path, r.image, {}, ExrPixelType::kHalf);
  spdlog::default_logger()->sinks().pop_back();
  const ImageRGB back = read_exr(path);
  std::filesystem::remove(path);
  int inf = 0;
  float back_peak = 0;
  for (float v : back.rgb) {
    inf += !std::isfinite(v);
    back_peak = std::max(back_peak, v);
  }
  EXPECT_TRUE(check("8 half output", "Inf/NaN values in the half EXR", inf, Bound::kAtMost, 0));
  EXPECT_EQ(back_peak, 65504.0f);
  const auto lines = sink->last_formatted();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("clamped to +-65504"), std::string::npos) << lines[0];
  EXPECT_NE(lines[0].find(path), std::string::npos) << lines[0];
}

}  // namespace
}  // namespace tessera::stability

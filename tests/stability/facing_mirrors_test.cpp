// SPDX-License-Identifier: Apache-2.0
// Case 7: two mirrors facing each other. Recursion stops at max_depth exactly (counted in
// secondary rays), and what comes back after k bounces is reflectance^k times what the last
// ray sees, per channel.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "render/integrator.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

class FacingMirrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("mirrors");
    // Two finite mirrors, z = 0 facing +z and z = 1 facing -z, spanning x in [-1, 2].
    write_text(dir_ + "/mirrors.obj",
               "v -1 -10 0\nv 2 -10 0\nv 2 10 0\nv -1 10 0\n"
               "v -1 -10 1\nv 2 -10 1\nv 2 10 1\nv -1 10 1\n"
               "f 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\n");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The eye sits midway between the mirrors at x = 0; render space has it at the origin.
  Scene scene(const std::string& objects, int max_depth) {
    return scene_from(R"({
      "camera": {"position": [0, 0, 0.5], "look_at": [1, 0, 0.5]},
      "image": {"width": 1, "height": 1, "spp": 1, "sampler": "center", "max_depth": )" +
                          std::to_string(max_depth) + R"(},
      "background": [1, 1, 1],
      "materials": {"m": {"type": "mirror", "reflectance": [0.9, 0.5, 0.99]}},
      "objects": [)" + objects + "]}", dir_ + "/m.json");
  }
  std::string dir_;
};

TEST_F(FacingMirrors, FiniteMirrorsReturnReflectanceToTheKAfterKBouncesOrZeroWhenCut) {
  // Direction with tan(theta) = 0.1 from the z axis: bounces at x = 0.05, 0.15, ..., 1.95
  // (k = 20, each 0.05 from the mirrors' edge at x = 2), then it escapes to the background.
  const Vec3f d = normalize(Vec3f{0.1f, 0.0f, 1.0f});
  const int k = 20;
  const Vec3d rho{0.9, 0.5, 0.99};
  double worst = 0;
  int wrong_counts = 0;
  for (int depth = 0; depth <= 30; ++depth) {
    RenderScene rs(scene(R"({"type": "mesh", "file": "mirrors.obj", "material": "m"})", depth), 0);
    RayCounts counts;
    const PixelSampler sampler(SamplerKind::kCenter, 0, 0, 0, 0, 0, 1);
    const Rgb L = trace_radiance(rs, {Vec3f(0.0f), d}, sampler, &counts);
    if (counts.secondary != uint64_t(std::min(k, depth))) ++wrong_counts;
    for (int c = 0; c < 3; ++c) {
      const double expected = k <= depth ? std::pow(rho[c], k) : 0.0;
      worst = std::max(worst, std::abs(double(L[c]) - expected) / std::pow(rho[c], k));
    }
  }
  EXPECT_TRUE(check("7 facing mirrors k=20", "max rel. error of rho^k (max_depth 0..30)", worst, Bound::kAtMost,
                    k * 0x1p-23));  // k float products, each within an ulp
  EXPECT_TRUE(check("7 facing mirrors k=20", "runs whose secondary rays != min(k, max_depth)", wrong_counts,
                    Bound::kAtMost, 0));
}

TEST_F(FacingMirrors, InfiniteMirrorsStopExactlyAtMaxDepth) {
  // Mirror planes never let the ray out: the recursion must end at max_depth, returning black.
  int worst_count_error = 0;
  for (int depth : {0, 1, 7, 64}) {
    RenderScene rs(scene(R"({"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "m"},
                            {"type": "plane", "point": [0, 0, 1], "normal": [0, 0, -1], "material": "m"})", depth), 0);
    RayCounts counts;
    const PixelSampler sampler(SamplerKind::kCenter, 0, 0, 0, 0, 0, 1);
    const Rgb L = trace_radiance(rs, {Vec3f(0.0f), normalize(Vec3f{0.3f, 0.1f, 1.0f})}, sampler, &counts);
    EXPECT_EQ(L, Rgb(0.0f)) << depth;
    worst_count_error = std::max(worst_count_error, std::abs(int(counts.secondary) - depth));
  }
  EXPECT_TRUE(check("7 infinite mirrors", "max |secondary rays - max_depth| (depth 0,1,7,64)", worst_count_error,
                    Bound::kAtMost, 0));
}

}  // namespace
}  // namespace tessera::stability

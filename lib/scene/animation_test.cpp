// SPDX-License-Identifier: Apache-2.0
#include "scene/animation.h"

#include <gtest/gtest.h>

#include "scene/scene_parser.h"

namespace tessera {
namespace {

const char* kAnimated = R"({
  "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0], "vfov_deg": 40},
  "materials": {"m": {"type": "diffuse"}},
  "objects": [{"type": "sphere", "name": "ball", "center": [0, 0, 0], "radius": 1, "material": "m"},
              {"type": "sphere", "name": "still", "center": [3, 0, 0], "radius": 1, "material": "m"}],
  "animation": {"frames": 21,
    "camera": [{"frame": 5, "position": [0, 0, 10], "vfov_deg": 40},
               {"frame": 15, "position": [10, 0, 10], "vfov_deg": 60}],
    "objects": {"ball": [{"frame": 0, "translate": [0, 0, 0]}, {"frame": 10, "translate": [0, 4, 0], "scale": 3},
                         {"frame": 20, "translate": [0, 0, 0]}]}}
})";

TEST(Animation, KeyframesInterpolateLinearlyAndHoldOutsideTheirRange) {
  const Scene s = parse_scene(kAnimated, "anim.json");
  EXPECT_EQ(s.frame_count(), 21);
  EXPECT_EQ(evaluate_frame(s, 0).camera.position, (Vec3d{0, 0, 10}));   // before the first key: held
  EXPECT_EQ(evaluate_frame(s, 10).camera.position, (Vec3d{5, 0, 10}));  // halfway
  EXPECT_DOUBLE_EQ(evaluate_frame(s, 10).camera.vfov_deg, 50.0);
  EXPECT_EQ(evaluate_frame(s, 20).camera.position, (Vec3d{10, 0, 10}));  // after the last: held
  const FrameState f5 = evaluate_frame(s, 5);
  EXPECT_EQ(f5.transforms[0].translate, (Vec3d{0, 2, 0}));
  EXPECT_EQ(f5.transforms[0].scale, (Vec3d{2, 2, 2}));
  EXPECT_EQ(f5.transforms[1].translate, (Vec3d{0, 0, 0}));  // not animated
  EXPECT_EQ(evaluate_frame(s, 15).transforms[0].translate, (Vec3d{0, 2, 0}));
}

TEST(Animation, AFrameIsAPureFunctionOfSceneAndFrameNumber) {
  const Scene a = parse_scene(kAnimated, "anim.json");
  const Scene b = parse_scene(kAnimated, "anim.json");
  for (int f : {7, 3, 7}) {
    EXPECT_EQ(evaluate_frame(a, f).camera.position, evaluate_frame(b, f).camera.position);
    EXPECT_EQ(evaluate_frame(a, f).transforms[0].translate, evaluate_frame(b, f).transforms[0].translate);
  }
}

TEST(Animation, LookAtScreenPlaneHasSquarePixelsAndTheRequestedFov) {
  const Scene s = parse_scene(kAnimated, "anim.json");
  const ScreenPlane sp = screen_plane(s.camera, 200, 100);
  const double w = length(sp.p1 - sp.p0), h = length(sp.p2 - sp.p0);
  EXPECT_NEAR(w / 200, h / 100, 1e-12);
  EXPECT_NEAR(h, 2 * std::tan(20.0 * 3.14159265358979 / 180), 1e-12);  // at distance 1
  EXPECT_NEAR(dot(sp.p1 - sp.p0, sp.p2 - sp.p0), 0.0, 1e-12);
}

}  // namespace
}  // namespace tessera

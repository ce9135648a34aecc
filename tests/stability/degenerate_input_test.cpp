// SPDX-License-Identifier: Apache-2.0
// Case 9: degenerate input. Zero-area triangles, duplicate vertices, NaN vertices and coincident
// faces (z-fighting) are dropped or resolved deterministically, never crash, and never change
// what the valid geometry looks like. (lib/scene/mesh_loader_test.cpp covers the loader alone on
// tinyobjloader's edge-case files.)
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "scene/scene_error.h"
#include "stability_util.h"

namespace tessera::stability {
namespace {

class DegenerateInput : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = make_temp_dir("degenerate"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  Scene scene(const std::string& objects, const std::string& camera = R"({"position": [0, 3, 0.001], "look_at": [0, 0, 0], "vfov_deg": 60})") {
    return scene_from(R"({"camera": )" + camera + R"(,
      "image": {"width": 48, "height": 48, "spp": 4, "max_depth": 2},
      "lights": [{"type": "directional", "direction": [0, -1, 0], "irradiance": 3}],
      "materials": {"red": {"type": "diffuse", "albedo": [0.8, 0, 0]}, "green": {"type": "diffuse", "albedo": [0, 0.8, 0]}},
      "objects": [)" + objects + "]}", dir_ + "/s.json");
  }
  std::string dir_;
};

TEST_F(DegenerateInput, BadTrianglesAreDroppedAndTheRestRendersAsWithoutThem) {
  const std::string quad = "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n";
  write_text(dir_ + "/clean.obj", quad + "f 1 2 3\nf 1 3 4\n");
  // Vertex 5 duplicates vertex 1; 6 and 7 are non-finite; 8 is collinear with 1 and 3. Only
  // the first two faces have area (the second uses the duplicate).
  write_text(dir_ + "/dirty.obj", quad +
             "v -1 0 -1\nv nan 0 0\nv 0 inf 0\nv 0 0 0\n"
             "f 1 2 3\nf 5 3 4\nf 1 1 3\nf 1 5 2\nf 1 8 3\nf 1 6 3\nf 7 2 3\nf 1 3 3\n");
  const Scene clean = scene(R"({"type": "mesh", "file": "clean.obj", "material": "red"})");
  const Scene dirty = scene(R"({"type": "mesh", "file": "dirty.obj", "material": "red"})");
  RenderScene a(clean, 0), b(dirty, 0);
  EXPECT_EQ(b.triangle_count(), 2u);
  const FrameResult ra = render_frame(a, 16, 2), rb = render_frame(b, 16, 2);
  int differ = 0;
  for (size_t i = 0; i < ra.image.rgb.size(); ++i) differ += ra.image.rgb[i] != rb.image.rgb[i];
  EXPECT_TRUE(check("9 degenerate triangles", "pixels differing from the clean mesh", differ, Bound::kAtMost, 0));
  // Only degenerate triangles: a clear error naming the file, no crash.
  write_text(dir_ + "/bad.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv nan 1 1\nf 1 2 3\nf 1 2 4\n");
  try {
    scene(R"({"type": "mesh", "file": "bad.obj", "material": "red"})");
    ADD_FAILURE() << "a mesh with no usable triangle was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.obj"), std::string::npos) << e.what();
  }
}

TEST_F(DegenerateInput, CoincidentFacesResolveDeterministicallyToOneOfThem) {
  // The same quad twice, red and green (z-fighting). Whichever Embree reports, the result must be
  // one of the two exact lit colors (never a blend, never black), and bit-identical across
  // separately built scenes and thread counts.
  write_text(dir_ + "/quad.obj", "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nf 1 2 3\nf 1 3 4\n");
  const std::string objs = R"({"type": "mesh", "file": "quad.obj", "material": "red"},
                              {"type": "mesh", "file": "quad.obj", "material": "green"})";
  RenderScene a(scene(objs), 0), b(scene(objs), 0);
  const FrameResult ra = render_frame(a, 16, 1), rb = render_frame(b, 7, 2);
  int differ = 0;
  for (size_t i = 0; i < ra.image.rgb.size(); ++i) differ += ra.image.rgb[i] != rb.image.rgb[i];
  EXPECT_TRUE(check("9 coincident faces", "pixels differing between two builds", differ, Bound::kAtMost, 0));
  const double lit = 0.8 / std::numbers::pi * 3;
  int bad = 0, red = 0, green = 0;
  // Only pixels whose whole footprint lies on the quad (|x|, |z| <= 1 on the plane y = 0, seen
  // from 3 above with a 60 degree field: the image spans +-3 tan 30 in x and z), with a margin
  // for the camera's 0.001 tilt.
  const double half = 3 * std::tan(std::numbers::pi / 6);
  auto inside = [&](int px) {
    const double lo = -half + 2 * half * px / 48.0, hi = -half + 2 * half * (px + 1) / 48.0;
    return lo > -0.99 && hi < 0.99;
  };
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 48; ++x) {
      if (!inside(x) || !inside(y)) continue;
      const float* p = ra.image.at(x, y);
      // A pixel's samples may split between the two faces; each sample is exactly one of them,
      // so per pixel r + g is the lit value.
      if (std::abs(p[0] + p[1] - lit) > 1e-5 * lit || p[2] != 0) ++bad;
      red += p[0] > 0;
      green += p[1] > 0;
    }
  }
  EXPECT_GT(red + green, 100);
  EXPECT_TRUE(check("9 coincident faces", "pixels not an exact mix of the two lit colors", bad, Bound::kAtMost, 0));
}

}  // namespace
}  // namespace tessera::stability

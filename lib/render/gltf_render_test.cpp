// SPDX-License-Identifier: Apache-2.0
// glTF scenes rendered, against analytic values and against the same scene written in JSON:
// lights (point = JSON point, spot cone edges), the camera's yfov/aspect (a sphere's silhouette),
// texels at the pixels they should cover, and an animation frame against a keyed JSON scene.
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "render/render_scene_internal.h"
#include "render/tile_renderer.h"
#include "support/gltf_test_builder.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using testing::GltfBuilder;

const std::vector<uint32_t> kQuadIdx = {0, 1, 2, 0, 2, 3};
std::vector<float> quad(float h) { return {-h, -h, 0, h, -h, 0, h, h, 0, -h, h, 0}; }
const nlohmann::json kGrey = {{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1}}, {"metallicFactor", 0}}}};

class GltfRenderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_gltf_render_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  Scene load(const GltfBuilder& b, int w, int h, SamplerKind sampler = SamplerKind::kCenter, int spp = 1,
             const SceneLoadOptions& o = {}) {
    b.write((dir_ / "s.gltf").string());
    return with(load_scene((dir_ / "s.gltf").string(), o), w, h, sampler, spp);
  }
  Scene load_json(const std::string& text, int w, int h, SamplerKind sampler, int spp) {
    std::ofstream(dir_ / "s.json") << text;
    return with(load_scene((dir_ / "s.json").string()), w, h, sampler, spp);
  }
  static Scene with(Scene s, int w, int h, SamplerKind sampler, int spp) {
    ImageOverrides o;
    o.width = w;
    o.height = h;
    o.sampler = sampler;
    o.spp = spp;
    apply_overrides(s, o);
    return s;
  }
  static ImageRGB render(const Scene& s, int frame = 0) {
    RenderScene rs(s, frame);
    return render_frame(rs, 8, 1).image;
  }
  fs::path dir_;
};

TEST_F(GltfRenderTest, DiffuseQuadUnderPointLightEqualsTheJsonScenePixelForPixel) {
  GltfBuilder b;
  b.node({{"mesh", b.mesh(quad(2), kQuadIdx, b.material(kGrey))}});
  b.node({{"camera", b.camera(0.7, 1)}, {"translation", {0, 0, 5}}});
  // 6830 cd = 10 W/sr at 683 lm/W.
  b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "point"}, {"intensity", 6830}})}}}}},
          {"translation", {0.5, 0.3, 2}}});
  const ImageRGB g = render(load(b, 24, 24, SamplerKind::kSobol, 4));

  std::ofstream(dir_ / "quad.obj") << "v -2 -2 0\nv 2 -2 0\nv 2 2 0\nv -2 2 0\nf 1 2 3\nf 1 3 4\n";
  const nlohmann::json json = {
      {"camera", {{"position", {0, 0, 5}}, {"look_at", {0, 0, 4}}, {"vfov_deg", 0.7 * 180 / std::numbers::pi}}},
      {"lights", {{{"type", "point"}, {"position", {0.5, 0.3, 2}}, {"intensity", 10}}}},
      {"materials", {{"d", {{"type", "diffuse"}, {"albedo", 0.5}}}}},
      {"objects", {{{"type", "mesh"}, {"file", "quad.obj"}, {"material", "d"}}}}};
  const ImageRGB j = render(load_json(json.dump(), 24, 24, SamplerKind::kSobol, 4));
  ASSERT_EQ(g.rgb.size(), j.rgb.size());
  size_t lit = 0;
  for (size_t i = 0; i < g.rgb.size(); ++i) {
    ASSERT_EQ(g.rgb[i], j.rgb[i]) << "value " << i;
    lit += g.rgb[i] > 0;
  }
  EXPECT_GT(lit, g.rgb.size() / 2);
}

TEST_F(GltfRenderTest, SpotLightConeEdgesWhereTheAnglesSay) {
  const double inner = 0.3, outer = 0.5;
  GltfBuilder b;
  b.node({{"mesh", b.mesh(quad(4), kQuadIdx,
                          b.material({{"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 1}}, {"metallicFactor", 0}}}}))}});
  b.node({{"camera", b.camera(1.2, 1)}, {"translation", {0, 0, 4}}});
  b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "spot"}, {"intensity", 683},
                                                                       {"spot", {{"innerConeAngle", inner}, {"outerConeAngle", outer}}}})}}}}},
          {"translation", {0, 0, 1}}});  // shines down its -Z, onto the quad
  const int n = 64;
  const Scene s = load(b, n, n);
  const ImageRGB img = render(s);
  const ScreenPlane sp = screen_plane(s.camera, n, n);
  int dark_outside = 0, lit_inside = 0;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const double u = (x + 0.5) / n, v = (y + 0.5) / n;
      const Vec3d d = sp.p0 + (sp.p1 - sp.p0) * u + (sp.p2 - sp.p0) * v - sp.eye;
      const Vec3d q = sp.eye + d * (-sp.eye.z / d.z);  // on z = 0
      const double r2 = q.x * q.x + q.y * q.y + 1, cos_axis = 1 / std::sqrt(r2);
      const double angle = std::acos(cos_axis);
      double fall = std::clamp((cos_axis - std::cos(outer)) / (std::cos(inner) - std::cos(outer)), 0.0, 1.0);
      fall *= fall;
      const double expected = 1 / std::numbers::pi * fall * cos_axis / r2;  // I = 1 W/sr, albedo 1
      const float got = img.at(x, y)[0];
      EXPECT_NEAR(got, expected, 1e-4) << x << "," << y << " angle " << angle;
      if (angle > outer + 0.01) {
        EXPECT_EQ(got, 0.0f);
        ++dark_outside;
      }
      if (angle < inner) {
        EXPECT_NEAR(got, cos_axis / r2 / std::numbers::pi, 1e-5);
        ++lit_inside;
      }
    }
  }
  EXPECT_GT(dark_outside, 100);
  EXPECT_GT(lit_inside, 30);
}

TEST_F(GltfRenderTest, YfovAndAspectExactBySphereSilhouette) {
  // A fine UV sphere of radius 1 at the origin, black against a white background.
  std::vector<float> p;
  std::vector<uint32_t> idx;
  const int seg = 256, rings = 128;
  for (int i = 0; i <= rings; ++i) {
    for (int j = 0; j <= seg; ++j) {
      const double th = std::numbers::pi * i / rings, ph = 2 * std::numbers::pi * j / seg;
      p.insert(p.end(), {float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph))});
    }
  }
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < seg; ++j) {
      const uint32_t a = uint32_t(i * (seg + 1) + j), c = a + uint32_t(seg + 1);
      idx.insert(idx.end(), {a, c, a + 1, a + 1, c, c + 1});
    }
  }
  const double yfov = 0.5, aspect = 2, D = 6;
  GltfBuilder b;
  b.node({{"mesh", b.mesh(p, idx, b.material(kGrey))}});
  b.node({{"camera", b.camera(yfov, aspect)}, {"translation", {0, 0, D}}});
  b.write((dir_ / "s.gltf").string());
  Scene s = load_scene((dir_ / "s.gltf").string());
  ImageOverrides o;
  o.height = 301;  // the width follows from the camera's aspect ratio
  o.sampler = SamplerKind::kCenter;
  o.spp = 1;
  apply_overrides(s, o);
  ASSERT_EQ(s.image.width, 602);
  s.background = Rgb(1.0f);
  const ImageRGB img = render(s);
  int across = 0, down = 0;
  for (int x = 0; x < img.width; ++x) across += img.at(x, 150)[0] == 0.0f;
  for (int y = 0; y < img.height; ++y) down += img.at(301, y)[0] == 0.0f;
  // Silhouette half-angle asin(R/D); on a screen of half-height tan(yfov/2) spanning H/2 pixels.
  const double radius_px = std::tan(std::asin(1 / D)) / std::tan(yfov / 2) * img.height / 2;
  EXPECT_NEAR(across, 2 * radius_px, 2.0);
  EXPECT_NEAR(down, 2 * radius_px, 2.0);
}

// A 4x4 PNG whose texel (i, j) (column, row) has sRGB bytes (40 i + 20, 40 j + 20, 100).
std::string png_4x4() {
  std::vector<uint8_t> px;
  for (int j = 0; j < 4; ++j) {
    for (int i = 0; i < 4; ++i) px.insert(px.end(), {uint8_t(40 * i + 20), uint8_t(40 * j + 20), 100});
  }
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  img.width = img.height = 4;
  img.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  png_image_write_to_memory(&img, nullptr, &size, 0, px.data(), 0, nullptr);
  std::string out(size, '\0');
  png_image_write_to_memory(&img, out.data(), &size, 0, px.data(), 0, nullptr);
  out.resize(size);
  return out;
}

double srgb(int c) {
  const double x = c / 255.0;
  return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
}

TEST_F(GltfRenderTest, TexelsAtTheExpectedPixelsAndTextureTransformShiftsThem) {
  for (const double offset : {0.0, 0.5}) {
    GltfBuilder b;
    nlohmann::json info = {{"index", b.texture(png_4x4())}};
    if (offset != 0) info["extensions"]["KHR_texture_transform"] = {{"offset", {offset, 0}}};
    const int m = b.material({{"pbrMetallicRoughness", {{"baseColorTexture", info}, {"metallicFactor", 0}}}});
    // uv (0, 0) is the image's top-left: vertex (-1, 1).
    b.node({{"mesh", b.mesh(quad(1), kQuadIdx, m, {0, 1, 1, 1, 1, 0, 0, 0})}});
    const double yfov = 0.9;
    b.node({{"camera", b.camera(yfov, 1)}, {"translation", {0, 0, 1 / std::tan(yfov / 2)}}});  // the quad fills the view
    // 683 pi lux = pi W/m^2 straight on: radiance = albedo.
    b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "directional"}, {"intensity", 683 * std::numbers::pi}})}}}}}});
    const ImageRGB img = render(load(b, 8, 8));
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 8; ++x) {
        const int i = (x / 2 + (offset != 0 ? 2 : 0)) % 4, j = y / 2;
        EXPECT_NEAR(img.at(x, y)[0], srgb(40 * i + 20), 1e-5) << x << "," << y << " offset " << offset;
        EXPECT_NEAR(img.at(x, y)[1], srgb(40 * j + 20), 1e-5) << x << "," << y;
        EXPECT_NEAR(img.at(x, y)[2], srgb(100), 1e-5) << x << "," << y;
      }
    }
  }
}

TEST_F(GltfRenderTest, TexturesCountAgainstTheScenesPixelLimit) {
  GltfBuilder b;
  const int m = b.material({{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", b.texture(png_4x4())}}}, {"metallicFactor", 0}}}});
  b.node({{"mesh", b.mesh(quad(1), kQuadIdx, m, {0, 1, 1, 1, 1, 0, 0, 0})}});
  b.node({{"camera", b.camera(0.9, 1)}, {"translation", {0, 0, 3}}});
  b.write((dir_ / "s.gltf").string());
  SceneLoadOptions o;
  o.max_texture_pixels = 15;  // the texture has 16
  try {
    load_scene((dir_ / "s.gltf").string(), o);
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("images[0] (from materials[0].pbrMetallicRoughness.baseColorTexture): image of "
                                         "4x4 pixels exceeds the texture limit (15 pixels in all)"),
              std::string::npos) << e.what();
  }
  o.max_texture_pixels = 16;
  EXPECT_EQ(load_scene((dir_ / "s.gltf").string(), o).textures.size(), 1u);
}

TEST_F(GltfRenderTest, AnimationFrameEqualsTheJsonSceneKeyedToThePose) {
  GltfBuilder b;
  b.node({{"mesh", b.mesh(quad(1), kQuadIdx, b.material(kGrey))}});
  b.node({{"camera", b.camera(0.8, 1)}, {"translation", {0, 0, 5}}});
  b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "point"}, {"intensity", 6830}})}}}}},
          {"translation", {0.2, 0.1, 2}}});
  const int t = b.floats({0, 1}, "SCALAR", 1);
  const int tr = b.floats({0, 0, 0, 1, 0.5, 0}, "VEC3", 3), sc = b.floats({1, 1, 1, 2, 2, 2}, "VEC3", 3);
  const int cam = b.floats({0, 0, 5, 0, 0, 7}, "VEC3", 3);
  b.doc["animations"] = {{{"samplers", {{{"input", t}, {"output", tr}}, {{"input", t}, {"output", sc}}, {{"input", t}, {"output", cam}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
                                        {{"sampler", 1}, {"target", {{"node", 0}, {"path", "scale"}}}},
                                        {{"sampler", 2}, {"target", {{"node", 1}, {"path", "translation"}}}}}}}};
  SceneLoadOptions o;
  o.gltf.fps = 4;  // frame 2 is t = 0.5: translate (0.5, 0.25, 0), scale 1.5, camera at z = 6
  const Scene g = load(b, 16, 16, SamplerKind::kSobol, 4, o);
  ASSERT_EQ(g.frame_count(), 5);

  std::ofstream(dir_ / "quad.obj") << "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n";
  const nlohmann::json json = {
      {"camera", {{"position", {0, 0, 5}}, {"look_at", {0, 0, 4}}, {"vfov_deg", 0.8 * 180 / std::numbers::pi}}},
      {"lights", {{{"type", "point"}, {"position", {0.2, 0.1, 2}}, {"intensity", 10}}}},
      {"materials", {{"d", {{"type", "diffuse"}, {"albedo", 0.5}}}}},
      {"objects", {{{"type", "mesh"}, {"name", "q"}, {"file", "quad.obj"}, {"material", "d"}}}},
      {"animation", {{"frames", 5},
                     {"camera", {{{"frame", 2}, {"position", {0, 0, 6}}, {"look_at", {0, 0, 5}}}}},
                     {"objects", {{"q", {{{"frame", 2}, {"translate", {0.5, 0.25, 0}}, {"scale", 1.5}}}}}}}}};
  const Scene j = load_json(json.dump(), 16, 16, SamplerKind::kSobol, 4);
  const ImageRGB gi = render(g, 2), ji = render(j, 2);
  for (size_t i = 0; i < gi.rgb.size(); ++i) ASSERT_EQ(gi.rgb[i], ji.rgb[i]) << "value " << i;
  const ImageRGB g0 = render(g, 0);
  EXPECT_NE(g0.rgb, gi.rgb);  // the pose does change the picture
}

}  // namespace
}  // namespace tessera

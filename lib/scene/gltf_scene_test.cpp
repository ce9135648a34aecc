// SPDX-License-Identifier: Apache-2.0
// glTF scenes at the Scene level: what the Blender export becomes, instancing, camera choice,
// animation frames, and one clear error (file + glTF path) for each kind of bad file.
#include "scene/gltf_scene.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "scene/animation.h"
#include "support/gltf_test_builder.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using testing::GltfBuilder;

const std::vector<float> kQuad = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
const std::vector<uint32_t> kQuadIdx = {0, 1, 2, 0, 2, 3};

class GltfSceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_gltf_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // A valid scene: a camera at z = 5 and a quad.
  GltfBuilder minimal() {
    GltfBuilder b;
    b.node({{"mesh", b.mesh(kQuad, kQuadIdx)}});
    b.node({{"camera", b.camera(0.8, 1.5)}, {"translation", {0, 0, 5}}});
    return b;
  }
  std::string write(const GltfBuilder& b, const std::string& name = "s.gltf") {
    b.write((dir_ / name).string());
    return (dir_ / name).string();
  }
  // The one error loading `b` gives.
  std::string error_of(const std::string& path, const SceneLoadOptions& o = {}) {
    try {
      load_scene(path, o);
    } catch (const SceneError& e) {
      return e.what();
    }
    return "(no error)";
  }
  std::string error_of(const GltfBuilder& b) { return error_of(write(b)); }
  fs::path dir_;
};

TEST_F(GltfSceneTest, BlenderExportBecomesCameraLightsMaterialsAndTexture) {
  const Scene s = load_scene(std::string(TESSERA_SOURCE_DIR) + "/tests/data/gltf/whitted_a.glb");
  EXPECT_NEAR(s.camera.vfov_deg * std::numbers::pi / 180, 0.5631968779732008, 1e-15);
  ASSERT_TRUE(s.camera_aspect.has_value());
  EXPECT_DOUBLE_EQ(*s.camera_aspect, 1.7777777777777777);
  EXPECT_EQ(s.image.height, 360);  // 640 wide by default, the camera's aspect
  EXPECT_NEAR(s.camera.position.z, 8.5, 1e-6);
  ASSERT_EQ(s.lights.size(), 3u);
  EXPECT_EQ(s.lights[0].type, Light::Type::kPoint);
  // 3000 W in Blender -> 163054 cd -> 3000 / (4 pi) W/sr, times the light's color.
  EXPECT_NEAR(s.lights[0].intensity.x, 3000 / (4 * std::numbers::pi), 1e-3);
  EXPECT_NEAR(s.lights[0].position.x, -4, 1e-6);
  EXPECT_EQ(s.lights[2].type, Light::Type::kDirectional);
  EXPECT_NEAR(s.lights[2].irradiance.x, 1.5, 1e-6);
  std::map<std::string, const Material*> m;
  for (const auto& mat : s.materials) m[mat.name] = &mat;
  EXPECT_EQ(m.at("whitted_a.glb:mirror")->type, Material::Type::kMirror);
  EXPECT_EQ(m.at("whitted_a.glb:glass")->type, Material::Type::kGlass);
  EXPECT_EQ(m.at("whitted_a.glb:glass")->ior, 1.5);
  EXPECT_EQ(m.at("whitted_a.glb:matte")->type, Material::Type::kDiffuse);
  ASSERT_EQ(m.at("whitted_a.glb:checker_floor")->albedo_texture, 0);
  ASSERT_EQ(s.textures.size(), 1u);
  EXPECT_EQ(s.textures[0].width, 512);
  EXPECT_TRUE(s.textures[0].nearest);
  EXPECT_EQ(s.objects.size(), 5u);
  EXPECT_TRUE(s.dependencies.empty());  // a .glb carries its buffers and images
}

TEST_F(GltfSceneTest, MaterialsMapToTheWhittedModelByTheNearestRule) {
  GltfBuilder b = minimal();
  b.material(nlohmann::json::object());  // glTF defaults: metallic 1, roughness 1: rough metal -> diffuse
  b.material({{"pbrMetallicRoughness", {{"baseColorFactor", {0.9, 0.8, 0.7, 1}}, {"roughnessFactor", 0}}}});
  b.material({{"pbrMetallicRoughness", {{"roughnessFactor", 0}, {"metallicFactor", 0}, {"baseColorFactor", {1, 0.5, 1, 1}}}},
              {"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 1}}}, {"KHR_materials_ior", {{"ior", 1.33}}}}}});
  b.material({{"emissiveFactor", {1, 0.5, 0.25}}, {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 4}}}}},
              {"pbrMetallicRoughness", {{"metallicFactor", 0}}}});
  const Scene s = load_scene(write(b));
  ASSERT_GE(s.materials.size(), 4u);
  EXPECT_EQ(s.materials[0].type, Material::Type::kDiffuse);
  EXPECT_EQ(s.materials[1].type, Material::Type::kMirror);
  EXPECT_EQ(s.materials[1].reflectance, Rgb(0.9f, 0.8f, 0.7f));
  EXPECT_EQ(s.materials[2].type, Material::Type::kGlass);
  EXPECT_EQ(s.materials[2].ior, 1.33);
  EXPECT_EQ(s.materials[2].transmittance, Rgb(1.0f, 0.5f, 1.0f));
  EXPECT_EQ(s.materials[3].type, Material::Type::kDiffuse);
  EXPECT_EQ(s.materials[3].emission, Rgb(4.0f, 2.0f, 1.0f));
}

TEST_F(GltfSceneTest, InstancesShareOneMeshAndComposeParentTransforms) {
  GltfBuilder b = minimal();
  const int child = b.node({{"mesh", 0}, {"translation", {0, 2, 0}}}, false);
  b.node({{"children", {child}}, {"scale", {2, 2, 2}}});
  const Scene s = load_scene(write(b));
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(s.objects[0].mesh, s.objects[1].mesh);
  const auto& m = *s.objects[1].transform.matrix;  // parent scale 2 times child translation (0, 2, 0)
  EXPECT_EQ(m[0], 2.0);
  EXPECT_EQ(m[7], 4.0);
}

TEST_F(GltfSceneTest, CameraByNameSceneIndexAndAspectFillingTheMissingSide) {
  GltfBuilder b = minimal();
  b.doc["cameras"][0]["name"] = "wide";
  b.node({{"name", "closeup_node"}, {"camera", b.camera(0.3)}, {"translation", {0, 0, 2}}});
  b.doc["scenes"].push_back({{"nodes", {0}}});
  const std::string p = write(b);
  SceneLoadOptions o;
  o.gltf.camera = "closeup_node";
  Scene s = load_scene(p, o);
  EXPECT_DOUBLE_EQ(s.camera.position.z, 2.0);
  EXPECT_FALSE(s.camera_aspect.has_value());
  o.gltf.camera = "nope";
  EXPECT_NE(error_of(p, o).find("--camera 'nope'"), std::string::npos) << error_of(p, o);
  EXPECT_NE(error_of(p, o).find("'wide', 'closeup_node'"), std::string::npos) << error_of(p, o);
  o.gltf.camera = "wide";
  s = load_scene(p, o);
  ImageOverrides ov;
  ov.height = 100;
  apply_overrides(s, ov);
  EXPECT_EQ(s.image.width, 150);
  o.gltf.camera.clear();
  o.gltf.scene_index = 1;  // scene 1 holds the quad only
  EXPECT_NE(error_of(p, o).find("scenes[1] has no camera"), std::string::npos) << error_of(p, o);
  o.gltf.scene_index = 2;
  EXPECT_NE(error_of(p, o).find("--scene-index 2"), std::string::npos);
}

TEST_F(GltfSceneTest, AnimationBecomesFramesAtTheGivenRate) {
  GltfBuilder b = minimal();
  const int in = b.floats({0, 1}, "SCALAR", 1), out = b.floats({0, 0, 0, 1, 0, 0}, "VEC3", 3);
  b.doc["animations"] = {{{"samplers", {{{"input", in}, {"output", out}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}}}};
  const std::string p = write(b);
  SceneLoadOptions o;
  o.gltf.fps = 4;
  const Scene s = load_scene(p, o);
  EXPECT_EQ(s.frame_count(), 5);  // t = 0, 0.25, ..., 1
  EXPECT_EQ((*evaluate_frame(s, 2).transforms[0].matrix)[3], 0.5);
  EXPECT_EQ((*evaluate_frame(s, 4).transforms[0].matrix)[3], 1.0);
  o.gltf.fps = 24;
  EXPECT_EQ(load_scene(p, o).frame_count(), 25);
}

// Blender writes its frame b at time b / fps, as float32: the last key's own frame must exist even
// where float32(b / fps) * fps rounds below b (it does for 20 of 24 fps).
TEST_F(GltfSceneTest, TheLastKeyFrameSurvivesFloat32Times) {
  GltfBuilder b = minimal();
  const float last = 20.0f / 24.0f;
  ASSERT_LT(double(last) * 24.0, 20.0);  // the rounding this test is about
  const int in = b.floats({0, last}, "SCALAR", 1), out = b.floats({0, 0, 0, 1, 0, 0}, "VEC3", 3);
  b.doc["animations"] = {{{"samplers", {{{"input", in}, {"output", out}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}}}};
  SceneLoadOptions o;
  o.gltf.fps = 24;
  const Scene s = load_scene(write(b), o);
  EXPECT_EQ(s.frame_count(), 21);
  EXPECT_EQ((*evaluate_frame(s, 20).transforms[0].matrix)[3], 1.0);
}

TEST_F(GltfSceneTest, BadFilesGetOneErrorNamingTheFileAndTheGltfPath) {
  {
    GltfBuilder b = minimal();
    b.node({{"mesh", b.mesh(kQuad, {0, 1, 7})}});
    EXPECT_NE(error_of(b).find("s.gltf: meshes[1].primitives[0].indices: index 7"), std::string::npos) << error_of(b);
  }
  {
    GltfBuilder b = minimal();
    b.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = b.floats({0, 0, 1, 1}, "VEC2", 2);
    EXPECT_NE(error_of(b).find("meshes[0].primitives[0].attributes.POSITION (accessors[2]): wrong element type"),
              std::string::npos) << error_of(b);
  }
  {
    GltfBuilder b = minimal();
    b.doc["accessors"][0]["count"] = 1000000000;
    EXPECT_NE(error_of(b).find("read past the end of bufferViews[0]"), std::string::npos) << error_of(b);
  }
  {
    GltfBuilder b = minimal();
    b.doc["nodes"][0]["children"] = {2};
    b.node({{"children", {0}}}, false);
    EXPECT_NE(error_of(b).find("cycle"), std::string::npos) << error_of(b);
  }
  {
    GltfBuilder b = minimal();
    b.material({{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", b.texture("GIF89a not a png")}}}}}});
    b.doc["meshes"][0]["primitives"][0]["material"] = 0;
    EXPECT_NE(error_of(b).find("images[0] (from materials[0].pbrMetallicRoughness.baseColorTexture): not a PNG or JPEG"),
              std::string::npos) << error_of(b);
  }
  {
    GltfBuilder b = minimal();
    nlohmann::json d = nlohmann::json::parse(b.text());
    d["buffers"][0]["uri"] = "missing.bin";
    std::ofstream(dir_ / "m.gltf") << d.dump();
    const std::string e = error_of((dir_ / "m.gltf").string());
    EXPECT_NE(e.find("m.gltf: invalid glTF"), std::string::npos) << e;
    EXPECT_NE(e.find("missing.bin"), std::string::npos) << e;
  }
  {
    GltfBuilder b = minimal();
    b.doc["cameras"][0] = {{"type", "orthographic"}, {"orthographic", {{"xmag", 1}, {"ymag", 1}, {"znear", 0.1}, {"zfar", 10}}}};
    EXPECT_NE(error_of(b).find("cameras[0].type: 'orthographic' cameras are not supported"), std::string::npos)
        << error_of(b);
  }
  {
    GltfBuilder b = minimal();
    b.doc["nodes"].erase(1);
    b.doc["scenes"][0]["nodes"] = {0};
    EXPECT_NE(error_of(b).find("has no camera"), std::string::npos) << error_of(b);
  }
  {
    std::ofstream(dir_ / "t.glb") << "glTF garbage";
    EXPECT_NE(error_of((dir_ / "t.glb").string()).find("t.glb: invalid glTF"), std::string::npos);
  }
}

TEST_F(GltfSceneTest, SeparateBuffersAreDependenciesForTheBundle) {
  fs::create_directories(dir_ / "sub");
  minimal().write_separate((dir_ / "sub" / "s.gltf").string(), "s data.bin");
  const Scene s = load_scene((dir_ / "sub" / "s.gltf").string());
  EXPECT_EQ(s.dependencies, std::vector<std::string>{"s data.bin"});
  EXPECT_EQ(s.meshes.size(), 1u);
}

TEST_F(GltfSceneTest, JsonSceneIncludesAGltfAndEditsOnTop) {
  GltfBuilder b = minimal();
  b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "point"}, {"intensity", 683}})}}}}}});
  fs::create_directories(dir_ / "export");
  b.write_separate((dir_ / "export" / "s.gltf").string(), "s.bin");
  std::ofstream(dir_ / "edit.json") << R"({"include": "export/s.gltf",
    "lights": [{"type": "directional", "direction": [0, -1, 0], "irradiance": 1}],
    "materials": {"m": {"type": "mirror"}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": "m"}]})";
  Scene s = load_scene((dir_ / "edit.json").string());
  EXPECT_DOUBLE_EQ(s.camera.position.z, 5.0);  // the glTF's camera
  ASSERT_EQ(s.lights.size(), 2u);              // the glTF's point light, then the file's sun
  EXPECT_EQ(s.lights[0].type, Light::Type::kPoint);
  EXPECT_EQ(s.lights[1].type, Light::Type::kDirectional);
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[1].type, SceneObject::Type::kSphere);
  EXPECT_EQ(s.materials[size_t(s.objects[1].material)].type, Material::Type::kMirror);
  EXPECT_EQ(s.dependencies, (std::vector<std::string>{"export/s.bin", "export/s.gltf"}));
  // A camera in the JSON replaces the glTF's.
  std::ofstream(dir_ / "edit.json") << R"({"include": "export/s.gltf",
    "camera": {"position": [0, 0, 9], "look_at": [0, 0, 0]}})";
  s = load_scene((dir_ / "edit.json").string());
  EXPECT_DOUBLE_EQ(s.camera.position.z, 9.0);
  std::ofstream(dir_ / "edit.json") << R"({"include": "export/nope.glb"})";
  EXPECT_NE(error_of((dir_ / "edit.json").string()).find("edit.json: include: "), std::string::npos)
      << error_of((dir_ / "edit.json").string());
}

TEST_F(GltfSceneTest, BuffersOutsideTheBundleAreRefused) {
  GltfBuilder b = minimal();
  nlohmann::json d = nlohmann::json::parse(b.text());
  fs::create_directories(dir_ / "bundle");
  std::ofstream(dir_ / "outside.bin") << std::string(100, '\0');
  d["buffers"][0]["uri"] = "../outside.bin";
  std::ofstream(dir_ / "bundle" / "s.gltf") << d.dump();
  SceneLoadOptions o;
  o.confine_to = (dir_ / "bundle").string();
  const std::string e = error_of((dir_ / "bundle" / "s.gltf").string(), o);
  EXPECT_NE(e.find("outside the scene bundle"), std::string::npos) << e;
}

// Skins and morph targets are not evaluated: each gets one warning naming the file and the
// first glTF path that has one, and the geometry loads as stored (bind pose, base shape).
TEST_F(GltfSceneTest, SkinsAndMorphTargetsAreWarnedOnceNamingTheGltfPath) {
  auto warnings_of = [&](const GltfBuilder& b) {
    const std::string p = write(b);
    auto sink = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(16);
    spdlog::default_logger()->sinks().push_back(sink);
    const Scene s = load_scene(p);
    spdlog::default_logger()->sinks().pop_back();
    EXPECT_EQ(s.meshes.at(0).positions.size(), 4u);
    return sink->last_formatted();
  };
  GltfBuilder plain = minimal();
  EXPECT_TRUE(warnings_of(plain).empty());

  GltfBuilder b = minimal();
  const int joint = b.node({{"name", "bone"}}, false);
  b.doc["skins"] = {{{"joints", {joint}}}};
  b.doc["nodes"][0]["skin"] = 0;
  b.node({{"mesh", 0}, {"skin", 0}, {"translation", {3, 0, 0}}});  // nodes[3]: a second skinned instance
  std::vector<std::string> lines = warnings_of(b);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("s.gltf: nodes[0].skin: skins are not supported: 2 skinned mesh instances render in the "
                          "bind pose"),
            std::string::npos)
      << lines[0];

  GltfBuilder m = minimal();
  const int offsets = m.floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
  m.doc["meshes"][0]["primitives"][0]["targets"] = {{{"POSITION", offsets}}};
  lines = warnings_of(m);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("s.gltf: meshes[0].primitives[0].targets: morph targets are not supported"), std::string::npos)
      << lines[0];
}

}  // namespace
}  // namespace tessera

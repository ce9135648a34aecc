// SPDX-License-Identifier: Apache-2.0
#include "scene/scene_parser.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <fstream>
#include <sstream>

namespace tessera {
namespace {

const char* kMinimal = R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
  "materials": {"m": {"type": "diffuse"}},
  "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}]})";

// Expects parse failure whose message contains every fragment.
void expect_error(const std::string& json, std::initializer_list<std::string> fragments) {
  try {
    parse_scene(json, "bad.json");
    FAIL() << "expected SceneError for " << json;
  } catch (const SceneError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("bad.json", 0), 0u) << msg;  // always names the file first
    for (const auto& f : fragments) EXPECT_NE(msg.find(f), std::string::npos) << "'" << f << "' not in: " << msg;
  }
}

std::string with(const std::string& from, const std::string& to) {
  std::string s = kMinimal;
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(SceneParser, MinimalSceneParsesWithDefaults) {
  const Scene s = parse_scene(kMinimal, "ok.json");
  EXPECT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.image.spp, 16);
  EXPECT_EQ(s.frame_count(), 1);
  EXPECT_EQ(s.image.sampler, SamplerKind::kSobol);
  EXPECT_FALSE(s.image.adaptive());
}

TEST(SceneParser, TargetErrorSettingsAndTheirErrors) {
  const Scene s = parse_scene(
      with("\"materials\"", "\"image\": {\"target_rmse\": 0.01, \"min_spp\": 8, \"max_spp\": 256}, \"materials\""),
      "ok.json");
  EXPECT_TRUE(s.image.adaptive());
  EXPECT_EQ(s.image.target_rmse, 0.01);
  EXPECT_EQ(s.image.min_spp, 8);
  EXPECT_EQ(s.image.max_spp, 256);
  expect_error(with("\"materials\"", "\"image\": {\"target_rmse\": 0}, \"materials\""), {"image.target_rmse"});
  expect_error(with("\"materials\"", "\"image\": {\"target_rmse\": 0.1, \"spp\": 4}, \"materials\""),
               {"image.target_rmse", "conflicts with image.spp"});
  expect_error(with("\"materials\"", "\"image\": {\"target_rmse\": 0.1, \"min_spp\": 64, \"max_spp\": 32}, \"materials\""),
               {"image.min_spp (64) must not exceed image.max_spp (32)"});
  expect_error(with("\"materials\"", "\"image\": {\"target_rmse\": 0.1, \"sampler\": \"cmj\"}, \"materials\""),
               {"image.target_rmse needs a progressive sampler"});
  expect_error(with("\"materials\"", "\"image\": {\"min_spp\": 1}, \"materials\""), {"image.min_spp", "[2, 65536]"});
}

TEST(SceneParser, RouletteWeightDefaultsToAHundredthAndIsAWeightInZeroToOne) {
  EXPECT_EQ(parse_scene(kMinimal, "ok.json").image.roulette_weight, 0.01);
  EXPECT_EQ(parse_scene(with("\"materials\"", "\"image\": {\"roulette_weight\": 0}, \"materials\""), "ok.json")
                .image.roulette_weight,
            0.0);
  expect_error(with("\"materials\"", "\"image\": {\"roulette_weight\": 1.5}, \"materials\""),
               {"image.roulette_weight", "[0, 1]"});
  expect_error(with("\"materials\"", "\"image\": {\"roulette_weight\": -0.1}, \"materials\""),
               {"image.roulette_weight"});
}

TEST(SceneParser, TargetErrorOverridesAreCheckedWithTheFlagsNames) {
  auto apply = [](ImageOverrides o) {
    Scene s = parse_scene(kMinimal, "ok.json");
    apply_overrides(s, o);
    return s;
  };
  auto expect_flag_error = [&](ImageOverrides o, const std::string& fragment) {
    try {
      apply(o);
      FAIL() << "expected an error containing " << fragment;
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  ImageOverrides o;
  o.target_rmse = 0.02;
  o.max_spp = 64;
  const Scene s = apply(o);
  EXPECT_TRUE(s.image.adaptive());
  EXPECT_EQ(s.image.max_spp, 64);
  for (double bad : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    ImageOverrides b;
    b.target_rmse = bad;
    expect_flag_error(b, "--target-rmse: must be a finite number > 0");
  }
  ImageOverrides both = o;
  both.spp = 16;
  expect_flag_error(both, "--spp and --target-rmse conflict");
  ImageOverrides inverted = o;
  inverted.min_spp = 128;
  expect_flag_error(inverted, "--min-spp (128) must not exceed --max-spp (64)");
  ImageOverrides bounds_only;
  bounds_only.max_spp = 64;
  expect_flag_error(bounds_only, "--max-spp bounds a render to a target error");
  ImageOverrides cmj = o;
  cmj.sampler = SamplerKind::kCmj;
  expect_flag_error(cmj, "--target-rmse needs a progressive sampler");
  ImageOverrides low = o;
  low.min_spp = 1;
  expect_flag_error(low, "--min-spp: must be in [2, 65536], got 1");
  EXPECT_EQ(sampler_from_name("stratified"), SamplerKind::kSobol);  // the old name of the default
}

TEST(SceneParser, SyntaxErrorsGiveLineAndColumn) {
  expect_error("{\n  \"camera\": {,\n}", {"bad.json:2:", "invalid JSON"});
}

TEST(SceneParser, UnknownFieldsAreRejectedWithTheirPath) {
  expect_error(with("\"radius\": 1", "\"radius\": 1, \"radios\": 2"), {"objects[0].radios", "unknown field"});
  expect_error(with("\"camera\"", "\"camra\": 1, \"camera\""), {"camra", "unknown field"});
}

TEST(SceneParser, WrongTypesNameTheFieldAndTheType) {
  expect_error(with("\"radius\": 1", "\"radius\": \"1\""), {"objects[0].radius", "must be", "number", "string"});
  expect_error(with("\"center\": [0, 0, 0]", "\"center\": [0, 0]"), {"objects[0].center", "3 numbers"});
  expect_error(with("\"objects\": [", "\"objects\": {\"x\": 1}, \"o\": ["), {"objects", "array"});
}

TEST(SceneParser, NonFiniteAndOutOfRangeValuesNameTheAllowedRange) {
  expect_error(with("\"radius\": 1", "\"radius\": 1e999"), {"1e999", "finite"});
  expect_error(with("\"radius\": 1", "\"radius\": -1"), {"objects[0].radius", "(0,", "got -1"});
  expect_error(with("\"materials\"", "\"image\": {\"spp\": 0}, \"materials\""), {"image.spp", "[1, 65536]", "got 0"});
  expect_error(with("\"materials\"", "\"image\": {\"width\": 2.5}, \"materials\""), {"image.width", "integer"});
  expect_error(with("{\"type\": \"diffuse\"}", "{\"type\": \"diffuse\", \"albedo\": [0.5, 2, 0]}"),
               {"materials.m.albedo[1]", "[0, 1]"});
  expect_error(with("{\"type\": \"diffuse\"}", "{\"type\": \"glass\", \"ior\": 0.5}"), {"materials.m.ior", "[1, 10]"});
}

TEST(SceneParser, ReferencesAndEnumsAreChecked) {
  expect_error(with("\"material\": \"m\"", "\"material\": \"nope\""), {"objects[0].material", "unknown material 'nope'", "'m'"});
  expect_error(with("\"type\": \"sphere\"", "\"type\": \"cube\""), {"objects[0].type", "'sphere', 'plane', 'mesh'"});
  expect_error(with("\"look_at\": [0, 0, 0]", "\"look_at\": [0, 0, 5]"), {"camera", "look_at must differ"});
  expect_error(with("\"radius\": 1", "\"radius\": 1, \"transform\": {\"scale\": [1, 2, 1]}"), {"uniform scale"});
}

TEST(SceneParser, MissingFilesAreNamed) {
  try {
    load_scene("/nonexistent/scene.json");
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.json: scene file not found"), std::string::npos);
  }
  expect_error(with("{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\"}",
                    "{\"type\": \"mesh\", \"file\": \"missing.obj\"}"),
               {"objects[0].file", "missing.obj", "not found"});
}

TEST(SceneParser, ScreenPlaneCameraAndOverrides) {
  Scene s = parse_scene(with("\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0]}",
                             "\"camera\": {\"eye\": [0, 0, 5], \"p0\": [-1, 1, 4], \"p1\": [1, 1, 4], \"p2\": [-1, -1, 4]}"),
                        "ok.json");
  EXPECT_EQ(s.camera.form, CameraDesc::Form::kScreenPlane);
  ImageOverrides o;
  o.spp = 7;
  o.width = 33;
  apply_overrides(s, o);
  EXPECT_EQ(s.image.spp, 7);
  EXPECT_EQ(s.image.width, 33);
  o.spp = 0;
  EXPECT_THROW(apply_overrides(s, o), SceneError);
  expect_error(with("\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0]}",
                    "\"camera\": {\"eye\": [0, 0, 5], \"p0\": [-1, 1, 4], \"p1\": [1, 1, 4], \"p2\": [3, 1, 4]}"),
               {"camera", "not collinear"});
}

TEST(SceneParser, AnimationKeysAreValidated) {
  const std::string anim = with("\"objects\"", R"("animation": {"frames": 10,
      "camera": [{"frame": 0, "position": [0, 0, 5]}, {"frame": 9, "position": [5, 0, 5]}],
      "objects": {"ball": [{"frame": 0, "translate": [0, 0, 0]}, {"frame": 9, "translate": [0, 2, 0]}]}},
      "objects")");
  const std::string named = [&] {
    std::string s = anim;
    return s.replace(s.find("\"type\": \"sphere\""), 16, "\"type\": \"sphere\", \"name\": \"ball\"");
  }();
  const Scene s = parse_scene(named, "ok.json");
  EXPECT_EQ(s.frame_count(), 10);
  EXPECT_EQ(s.animation.camera.size(), 2u);
  expect_error(anim, {"animation.objects.ball", "no object is named 'ball'"});
  std::string late = named;
  late.replace(late.find("\"frame\": 9, \"position\""), 10, "\"frame\": 10");
  expect_error(late, {"animation.camera[1].frame", "[0, 9]"});
}

}  // namespace
}  // namespace tessera

namespace tessera {
namespace {

TEST(SceneParser, TheDocumentedFullExampleParses) {
  // docs/scene-format.md's example must stay valid: parse the first ```json block.
  std::ifstream in(std::string(TESSERA_SOURCE_DIR) + "/docs/scene-format.md");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const auto start = doc.find("```json\n");
  ASSERT_NE(start, std::string::npos);
  const auto end = doc.find("```", start + 8);
  const std::string json = doc.substr(start + 8, end - start - 8);
  // Mesh paths are relative to the scene file: pretend it sits in scenes/.
  const Scene s = parse_scene(json, std::string(TESSERA_SOURCE_DIR) + "/scenes/doc_example.json");
  EXPECT_EQ(s.objects.size(), 5u);
  EXPECT_EQ(s.frame_count(), 48);
  EXPECT_EQ(s.dependencies.size(), 3u);  // the PLY, the OBJ and its MTL
}

TEST(SceneParser, ShowcaseScenesParse) {
  for (const char* name : {"whitted", "cornell", "bunny", "armadillo"}) {
    SCOPED_TRACE(name);
    const Scene s = load_scene(std::string(TESSERA_SOURCE_DIR) + "/scenes/" + name + ".json");
    EXPECT_FALSE(s.objects.empty());
  }
}

}  // namespace
}  // namespace tessera

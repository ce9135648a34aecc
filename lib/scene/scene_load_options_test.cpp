// SPDX-License-Identifier: Apache-2.0
// SceneLoadOptions: what the coordinator applies to scenes from bundles.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "scene/scene_parser.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

const std::string kCamera = R"("camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40})";

// A scene in scenes/ that instances the Cornell box mesh `copies` times with its own material
// (each instance is a copy of the mesh), plus one sphere.
std::string instancing_scene(int copies) {
  std::string objects = R"({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"})";
  for (int i = 0; i < copies; ++i) {
    objects += R"(, {"type": "mesh", "file": "models/CornellBox-Sphere.obj", "material": "m"})";
  }
  return "{" + kCamera + R"(, "materials": {"m": {"type": "diffuse", "albedo": 0.5}}, "objects": [)" + objects + "]}";
}

TEST(SceneLoadOptions, PrimitiveLimitCountsEveryInstanceAndIsExact) {
  const std::string path = std::string(TESSERA_SOURCE_DIR) + "/scenes/virtual.json";
  const Scene one = parse_scene(instancing_scene(1), path);
  const uint64_t per_mesh = primitive_count(one) - 1;
  ASSERT_GT(per_mesh, 10u);
  SceneLoadOptions o;
  o.max_primitives = 1 + 3 * per_mesh;
  EXPECT_EQ(primitive_count(parse_scene(instancing_scene(3), path, o)), 1 + 3 * per_mesh);
  o.max_primitives -= 1;
  try {
    parse_scene(instancing_scene(3), path, o);
    FAIL() << "accepted over the limit";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("objects[3]: the scene has more than " + std::to_string(o.max_primitives) +
                                         " primitives"),
              std::string::npos)
        << e.what();
  }
}

TEST(SceneLoadOptions, ConfinementRefusesMeshesOutsideTheDirectory) {
  const fs::path scenes = fs::path(TESSERA_SOURCE_DIR) / "scenes";
  SceneLoadOptions o;
  o.confine_to = scenes.string();
  const std::string inside = "{" + kCamera + R"(, "objects": [{"type": "mesh", "file": "models/CornellBox-Sphere.obj"}]})";
  EXPECT_NO_THROW(parse_scene(inside, (scenes / "x.json").string(), o));
  for (const std::string file : {"../README.md", "/etc/passwd", "models/../../scenes/../README.md"}) {
    const std::string text = "{" + kCamera + R"(, "objects": [{"type": "mesh", "file": ")" + file + R"("}]})";
    try {
      parse_scene(text, (scenes / "x.json").string(), o);
      FAIL() << file << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("is outside the scene bundle"), std::string::npos) << e.what();
    }
  }
  // A path that climbs out and back in stays inside.
  const std::string back = "{" + kCamera + R"(, "objects": [{"type": "mesh", "file": "../scenes/models/CornellBox-Sphere.obj"}]})";
  EXPECT_NO_THROW(parse_scene(back, (scenes / "x.json").string(), o));
}

}  // namespace
}  // namespace tessera

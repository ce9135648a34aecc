// SPDX-License-Identifier: Apache-2.0
// glTF scenes on the farm: the Blender export (.glb, buffers and texture inside) and a
// separate-files .gltf (its .bin must travel in the bundle) render bit-identical to `tessera render`.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "farm_harness.h"
#include "support/gltf_test_builder.h"

namespace tessera::farmtest {
namespace {

TEST(FarmGltf, BlenderGlbAndSeparateGltfBitIdenticalToRender) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1");
  const fs::path glb = source("tests/data/gltf/whitted_a.glb");
  const std::vector<std::string> settings{"--width", "96", "--spp", "2"};
  std::vector<std::string> argv{"submit", glb.string(), "--coordinator", farm.address(), "-o",
                                (farm.dir() / "out" / "glb_####.exr").string(), "--tile", "16"};
  argv.insert(argv.end(), settings.begin(), settings.end());
  CliResult r = farm.cli(argv);
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  EXPECT_EQ(compare_exr(farm.dir() / "out" / "glb_0000.exr", reference_frame(glb, 0, settings)), "");

  // A .gltf whose buffer is a separate file: the bundle must carry it.
  testing::GltfBuilder b;
  b.node({{"mesh", b.mesh({-2, -2, 0, 2, -2, 0, 2, 2, 0, -2, 2, 0}, {0, 1, 2, 0, 2, 3},
                          b.material({{"pbrMetallicRoughness", {{"metallicFactor", 0}}}}))}});
  b.node({{"camera", b.camera(0.7, 1.5)}, {"translation", {0, 0, 5}}});
  b.node({{"extensions", {{"KHR_lights_punctual", {{"light", b.light({{"type", "point"}, {"intensity", 6830}})}}}}},
          {"translation", {0.5, 0.3, 2}}});
  fs::create_directories(farm.dir() / "scene");
  const fs::path gltf = farm.dir() / "scene" / "quad.gltf";
  b.write_separate(gltf.string(), "quad.bin");
  r = farm.cli({"submit", gltf.string(), "--coordinator", farm.address(), "-o",
                (farm.dir() / "out" / "sep_####.exr").string(), "--tile", "16", "--width", "48", "--spp", "2"});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  EXPECT_EQ(compare_exr(farm.dir() / "out" / "sep_0000.exr", reference_frame(gltf, 0, {"--width", "48", "--spp", "2"})),
            "");
}

// A glTF with two scenes, two cameras in the second and an animated quad: a job's --scene-index,
// --camera and --fps travel in its overrides to the coordinator's SQLite store and to workers,
// across a kill -9 of the coordinator before any worker has seen the job.
TEST(FarmGltf, CameraSceneIndexAndFpsSurviveARestartAndEqualRender) {
  testing::GltfBuilder b;
  const int grey = b.material({{"pbrMetallicRoughness", {{"metallicFactor", 0}}}});
  const int quad = b.mesh({-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0}, {0, 1, 2, 0, 2, 3}, grey);
  const int point = b.light({{"type", "point"}, {"intensity", 6830}});
  const nlohmann::json lit = {{"KHR_lights_punctual", {{"light", point}}}};
  // Scene 0 (the file's default): the quad at rest, seen from the front.
  b.node({{"mesh", quad}});
  b.node({{"camera", b.camera(0.8, 1)}, {"translation", {0, 0, 5}}});
  b.node({{"extensions", lit}, {"translation", {0.2, 0.1, 2}}});
  // Scene 1: the quad moving, a front camera first and a camera from the side ("side").
  const int moving = b.node({{"mesh", quad}}, false);
  const int front = b.node({{"camera", b.camera(0.8, 1)}, {"translation", {0, 0, 5}}}, false);
  const int side = b.node({{"name", "side"}, {"camera", b.camera(0.9, 1)}, {"translation", {3, 0, 4}},
                           {"rotation", {0, 0.3007, 0, 0.9537}}},  // 35 degrees about +y, towards the quad
                          false);
  const int light = b.node({{"extensions", lit}, {"translation", {1, 0.5, 2}}}, false);
  b.doc["scenes"].push_back({{"nodes", {moving, front, side, light}}});
  const int t = b.floats({0, 1}, "SCALAR", 1), tr = b.floats({-1, 0, 0, 1, 0.5, 0}, "VEC3", 3);
  b.doc["animations"] = {{{"samplers", {{{"input", t}, {"output", tr}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", moving}, {"path", "translation"}}}}}}}};

  Farm farm;
  farm.start_server();
  fs::create_directories(farm.dir() / "scene");
  const fs::path gltf = farm.dir() / "scene" / "two_scenes.gltf";
  b.write(gltf.string());
  const std::vector<std::string> flags{"--scene-index", "1", "--camera", "side", "--fps", "10",
                                       "--width", "40", "--height", "40", "--spp", "2"};
  std::vector<std::string> argv{"submit", gltf.string(), "--coordinator", farm.address(), "--tile", "16",
                                "--frames", "3-4", "--detach"};
  argv.insert(argv.end(), flags.begin(), flags.end());
  CliResult s = farm.cli(argv);
  ASSERT_EQ(s.code, 0) << s.output << farm.server().log();
  const std::string job = job_id_from(s.output);
  // SubmitJob answers once the job is durable; no worker has seen it when the coordinator dies.
  farm.restart_server();
  farm.start_worker("w1");
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string()});
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  for (int f : {3, 4}) {
    EXPECT_EQ(compare_exr(out / ("f_000" + std::to_string(f) + ".exr"), reference_frame(gltf, f, flags)), "") << f;
  }
  // Each flag changes the picture, so the equality above cannot hold with one of them dropped.
  const std::vector<std::string> size{"--width", "40", "--height", "40", "--spp", "2"};
  auto without = [&](const std::string& flag) {
    std::vector<std::string> v;
    for (size_t i = 0; i < flags.size(); i += 2) {
      if (flags[i] != flag) v.insert(v.end(), {flags[i], flags[i + 1]});
    }
    return v;
  };
  EXPECT_NE(compare_exr(reference_frame(gltf, 3, flags), reference_frame(gltf, 3, without("--camera"))), "");
  EXPECT_NE(compare_exr(reference_frame(gltf, 3, flags), reference_frame(gltf, 3, without("--fps"))), "");
  EXPECT_NE(compare_exr(reference_frame(gltf, 0, size), reference_frame(gltf, 0, {"--scene-index", "1", "--width",
                                                                                  "40", "--height", "40", "--spp", "2"})),
            "");
}

TEST(FarmGltf, BadGltfFlagsAreRefusedNamingTheFlagAndRange) {
  testing::GltfBuilder b;
  b.node({{"mesh", b.mesh({-1, -1, 0, 1, -1, 0, 1, 1, 0}, {0, 1, 2})}});
  b.node({{"camera", b.camera(0.8, 1)}, {"translation", {0, 0, 5}}});
  Farm farm;
  farm.start_server();
  const fs::path gltf = farm.dir() / "tri.gltf";
  b.write(gltf.string());
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases{
      {{"--scene-index", "3"}, "--scene-index 3: must be in [0, 0]"},
      {{"--scene-index", "-2"}, "--scene-index: must be >= 0, got -2"},
      {{"--fps", "0"}, "--fps: must be in (0, 1000], got 0"},
      {{"--fps", "5000"}, "--fps: must be in (0, 1000], got 5000"},
      {{"--camera", "nope"}, "--camera 'nope': no camera or camera node"},
  };
  for (const auto& [flags, message] : cases) {
    std::vector<std::string> argv{"submit", gltf.string(), "--coordinator", farm.address(), "--detach"};
    argv.insert(argv.end(), flags.begin(), flags.end());
    const CliResult r = farm.cli(argv);
    EXPECT_EQ(r.code, 2) << flags[0] << ": " << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << r.output;
  }
  const CliResult json = farm.cli({"submit", source("scenes/whitted.json").string(), "--coordinator", farm.address(),
                                   "--detach", "--scene-index", "0"});
  EXPECT_EQ(json.code, 2) << json.output;
  EXPECT_NE(json.output.find("apply to glTF scenes (.gltf, .glb) only"), std::string::npos) << json.output;
}

// Texture pixels are one of the coordinator's limits: the Blender scene's checker texture is over
// a limit of 15 pixels, and the refusal names the limit and the flag.
TEST(FarmGltf, TexturePixelsAreLimitedByTheServersFlag) {
  Farm farm;
  farm.start_server({"--max-texture-pixels", "15"});
  const CliResult r = farm.cli({"submit", source("tests/data/gltf/whitted_a.glb").string(), "--coordinator",
                                farm.address(), "--detach", "--width", "32"});
  EXPECT_EQ(r.code, 1) << r.output;  // RESOURCE_EXHAUSTED: a limit, not a bad scene (INVALID_ARGUMENT exits 2)
  EXPECT_NE(r.output.find("exceeds the texture limit (15 pixels in all) (tessera-server --max-texture-pixels)"),
            std::string::npos)
      << r.output;
}

}  // namespace
}  // namespace tessera::farmtest

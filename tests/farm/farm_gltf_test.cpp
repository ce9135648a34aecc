// glTF scenes on the farm: the Blender export (.glb, buffers and texture inside) and a
// separate-files .gltf (its .bin must travel in the bundle) render bit-identical to `tessera render`.
#include <gtest/gtest.h>

#include "farm_harness.h"
#include "scene/gltf_test_builder.h"

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

}  // namespace
}  // namespace tessera::farmtest

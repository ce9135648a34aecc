// SPDX-License-Identifier: Apache-2.0
// The integrator's packets against their lanes traced alone: a pixel's samples traced together
// (trace_radiance_packet: Embree packets for camera, shadow, reflection and refraction rays, the
// work around them in SIMD across lanes) must give each sample the radiance it gets traced as a
// packet of one (trace_radiance), bit for bit, and count the same rays, on every SIMD target this
// machine runs, and the same bits on every target: a lane depends on nothing but its own ray and
// sampler, whatever the vector width. What those radiances
// should be is checked against analytic values elsewhere (tile_renderer_test.cpp,
// gltf_render_test.cpp, tests/stability).
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <bit>
#include <string>
#include <vector>

#include "render/integrator.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

// Appends every lane's radiance bits to *bits, for the comparison across targets.
void check_packets_against_lanes_alone(const RenderScene& rs, std::vector<uint32_t>* bits) {
  const ImageSettings& img = rs.image();
  const auto& cam = rs.camera();
  constexpr int P = RenderScene::kPacket;
  RayCounts alone_counts, packet_counts;
  uint64_t secondary_lanes = 0;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      // 3 to 8 samples: partly filled packets too.
      const int n = 3 + (x + y) % 6;
      PixelSampler samplers[P];
      Ray rays[P];
      for (int i = 0; i < n; ++i) {
        samplers[i] = PixelSampler(img.sampler, img.seed, 0, x, y, uint32_t(i), uint32_t(n));
        float su, sv;
        samplers[i].pixel_offset(&su, &sv);
        rays[i] = {Vec3f(0.0f), normalize(cam.p0 + cam.du * ((float(x) + su) / float(img.width)) +
                                          cam.dv * ((float(y) + sv) / float(img.height)))};
      }
      Rgb packet[P];
      const uint64_t before = packet_counts.secondary;
      trace_radiance_packet(rs, rays, samplers, n, &packet_counts, packet);
      secondary_lanes += packet_counts.secondary - before;
      for (int i = 0; i < n; ++i) {
        const Rgb alone = trace_radiance(rs, rays[i], samplers[i], &alone_counts);
        for (int c = 0; c < 3; ++c) {
          bits->push_back(std::bit_cast<uint32_t>(packet[i][c]));
          ASSERT_EQ(std::bit_cast<uint32_t>(packet[i][c]), std::bit_cast<uint32_t>(alone[c]))
              << "pixel " << x << "," << y << " sample " << i << " channel " << c;
        }
      }
    }
  }
  EXPECT_EQ(packet_counts.shadow, alone_counts.shadow);
  EXPECT_EQ(packet_counts.secondary, alone_counts.secondary);
  EXPECT_GT(secondary_lanes, 100u) << "the scene must send reflection or refraction rays";
}

class IntegratorPacketTest : public ::testing::TestWithParam<const char*> {};

TEST_P(IntegratorPacketTest, EveryLaneEqualsItsSampleTracedAloneBitForBit) {
  Scene scene = load_scene(std::string(TESSERA_SOURCE_DIR) + "/" + GetParam());
  scene.image.width = 48;
  scene.image.height = 27;
  const RenderScene rs(scene, 0);
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  // Every target gives the first one's bits too: the SIMD stages do not depend on the width.
  std::vector<uint32_t> first;
  for (int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    std::vector<uint32_t> bits;
    check_packets_against_lanes_alone(rs, &bits);
    if (HasFatalFailure()) break;
    if (first.empty()) {
      first = bits;
    } else {
      ASSERT_EQ(bits.size(), first.size());
      for (size_t k = 0; k < bits.size(); ++k) ASSERT_EQ(bits[k], first[k]) << "value " << k << " differs from " << hwy::TargetName(targets[0]);
    }
  }
  EXPECT_GT(targets.size(), 1u) << "only one SIMD target to compare";
  hwy::SetSupportedTargetsForTest(0);
}

INSTANTIATE_TEST_SUITE_P(Showcase, IntegratorPacketTest,
                         ::testing::Values("scenes/whitted.json", "scenes/cornell.json", "scenes/bunny.json",
                                           // spot and point lights, an emissive panel, smooth meshes, a texture
                                           "tests/data/gltf/whitted_a.glb"),
                         [](const auto& info) {
                           std::string name = info.param;
                           name = name.substr(name.rfind('/') + 1);
                           return name.substr(0, name.find('.'));
                         });

}  // namespace
}  // namespace tessera

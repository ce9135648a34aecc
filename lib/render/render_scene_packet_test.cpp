// SPDX-License-Identifier: Apache-2.0
// The packet queries against the single-ray ones (an independent code path inside Embree), and
// a lane's result against the packet it is in: it must not depend on its lane or companions.
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <tuple>

#include "render/ray_batch.h"
#include "render/render_scene_internal.h"
#include "render/sampler.h"
#include "render/test_hits.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

// Deterministic rays from the eye over the whole view, plus shadow-like rays between hit points.
std::vector<Ray> camera_rays(const RenderScene& rs, int count) {
  std::vector<Ray> rays;
  const auto& cam = rs.camera();
  for (int i = 0; i < count; ++i) {
    const uint64_t h = mix64(uint64_t(i) + 12345);
    const float u = to_unit_float(uint32_t(h)), v = to_unit_float(uint32_t(h >> 32));
    rays.push_back({Vec3f(0.0f), normalize(cam.p0 + cam.du * u + cam.dv * v)});
  }
  return rays;
}

void expect_same_hit(bool found_a, const Hit& a, bool found_b, const Hit& b, bool exact, const std::string& what) {
  ASSERT_EQ(found_a, found_b) << what;
  if (!found_a) return;
  ASSERT_EQ(a.prim, b.prim) << what;
  ASSERT_EQ(a.material, b.material) << what;
  if (exact) {
    EXPECT_EQ(a.t, b.t) << what;
    EXPECT_EQ(a.p.x, b.p.x) << what;
    EXPECT_EQ(a.n.z, b.n.z) << what;
  } else {
    EXPECT_NEAR(a.t, b.t, 1e-5f * a.t) << what;
  }
}

// (scene file, triangle test): packets must match single rays under every triangle test.
class PacketTest : public ::testing::TestWithParam<std::tuple<const char*, TriangleTest>> {
 protected:
  Scene scene() const { return load_scene(std::string(TESSERA_SOURCE_DIR) + "/scenes/" + std::get<0>(GetParam())); }
  RenderOptions options() const { return {std::get<1>(GetParam())}; }
};

TEST_P(PacketTest, PacketHitsMatchSingleRayHitsAndDoNotDependOnTheLane) {
  const RenderScene rs(scene(), 0, options());
  // Our own primitive tests (spheres, planes, watertight triangles) run the same code per lane in
  // both paths: bit-identical. Embree's triangle tests have separate packet kernels.
  const bool own_triangles = options().triangles == TriangleTest::kWatertight;
  const std::vector<Ray> rays = camera_rays(rs, 200);
  constexpr int P = RenderScene::kPacket;
  const PrimRef none[P] = {};
  int hits = 0;
  for (size_t base = 0; base + P <= rays.size(); base += P) {
    Hit packet[P], single;
    bool found[P];
    rs.intersect_packet(&rays[base], none, P, packet, found);
    for (int i = 0; i < P; ++i) {
      const bool f = rs.intersect(rays[base + i], PrimRef{}, &single);
      hits += f;
      const bool exact = !f || own_triangles || single.prim.kind != PrimRef::Kind::kTriangle;
      expect_same_hit(f, single, found[i], packet[i], exact, "ray " + std::to_string(base + i));
    }
    // The same ray alone in a 1-lane packet, and in the last lane of a reversed packet: identical.
    for (int i = 0; i < P; ++i) {
      Hit alone;
      bool found_alone;
      rs.intersect_packet(&rays[base + i], none, 1, &alone, &found_alone);
      expect_same_hit(found[i], packet[i], found_alone, alone, true, "alone " + std::to_string(base + i));
    }
    Ray reversed[P];
    for (int i = 0; i < P; ++i) reversed[i] = rays[base + P - 1 - i];
    Hit rev[P];
    bool found_rev[P];
    rs.intersect_packet(reversed, none, P, rev, found_rev);
    for (int i = 0; i < P; ++i) {
      expect_same_hit(found[i], packet[i], found_rev[P - 1 - i], rev[P - 1 - i], true, "reversed");
    }
  }
  EXPECT_GT(hits, 100);
}

TEST_P(PacketTest, PacketTransmittanceMatchesSingleRays) {
  const RenderScene rs(scene(), 0, options());
  const std::vector<Ray> rays = camera_rays(rs, 160);
  // Shadow rays from each hit toward the camera-side light position, up and to the left.
  std::vector<Ray> shadow;
  std::vector<PrimRef> from;
  for (const Ray& r : rays) {
    Hit h;
    if (!rs.intersect(r, PrimRef{}, &h)) continue;
    const Vec3f n = dot(r.d, h.n) < 0 ? h.n : -h.n;
    const Vec3f target(-2.0f, 3.0f, -1.0f);
    const Vec3f w = normalize(target - h.p);
    shadow.push_back({offset_ray_origin(h.p, h.p_err, n, w), w, length(target - h.p)});
    from.push_back(h.prim);
  }
  constexpr int P = RenderScene::kPacket;
  int blocked = 0, open = 0;
  for (size_t base = 0; base + P <= shadow.size(); base += P) {
    Rgb T[P];
    rs.transmittance_packet(&shadow[base], &from[base], P, T);
    for (int i = 0; i < P; ++i) {
      const Rgb t1 = rs.transmittance(shadow[base + i], from[base + i]);
      EXPECT_EQ(t1.x, T[i].x) << "shadow ray " << base + i;
      EXPECT_EQ(t1.y, T[i].y) << "shadow ray " << base + i;
      EXPECT_EQ(t1.z, T[i].z) << "shadow ray " << base + i;
      (t1.x == 0 && t1.y == 0 && t1.z == 0 ? blocked : open)++;
    }
  }
  EXPECT_GT(blocked + open, 50);
}

// Full packets of shadow rays that all leave the ground of a scene with one opaque plane (the
// Whitted showcase's checker floor): transmittance_packet skips the opaque-plane test for them (a
// ray never meets the plane it leaves). Toward both of the scene's lights, some rays blocked by
// the spheres and some open, every lane must still be the single ray's answer.
TEST(PacketGround, ShadowRaysLeavingTheOnlyOpaquePlaneMatchSingleRays) {
  const RenderScene rs(load_scene(std::string(TESSERA_SOURCE_DIR) + "/scenes/whitted.json"), 0);
  ASSERT_EQ(rs.point_lights().size(), 2u);
  const std::vector<Ray> rays = camera_rays(rs, 4000);
  constexpr int P = RenderScene::kPacket;
  int blocked = 0, open = 0, packets = 0;
  for (const auto& light : rs.point_lights()) {
    std::vector<Ray> shadow;
    std::vector<PrimRef> from;
    for (const Ray& r : rays) {
      Hit h;
      if (!rs.intersect(r, PrimRef{}, &h) || h.prim.kind != PrimRef::Kind::kPlane) continue;
      const Vec3f n = dot(r.d, h.n) < 0 ? h.n : -h.n;
      const Vec3f w = normalize(light.position - h.p);
      if (!(dot(w, n) > 0)) continue;
      shadow.push_back({offset_ray_origin(h.p, h.p_err, n, w), w, length(light.position - h.p) * (1.0f - 1e-4f)});
      from.push_back(h.prim);
    }
    for (size_t base = 0; base + P <= shadow.size(); base += P, ++packets) {
      Rgb T[P];
      rs.transmittance_packet(&shadow[base], &from[base], P, T);
      for (int i = 0; i < P; ++i) {
        const Rgb t1 = rs.transmittance(shadow[base + i], from[base + i]);
        ASSERT_EQ(std::bit_cast<uint32_t>(t1.x), std::bit_cast<uint32_t>(T[i].x)) << "shadow ray " << base + i;
        ASSERT_EQ(std::bit_cast<uint32_t>(t1.y), std::bit_cast<uint32_t>(T[i].y)) << "shadow ray " << base + i;
        ASSERT_EQ(std::bit_cast<uint32_t>(t1.z), std::bit_cast<uint32_t>(T[i].z)) << "shadow ray " << base + i;
        (t1.x == 0 && t1.y == 0 && t1.z == 0 ? blocked : open)++;
      }
    }
  }
  EXPECT_GT(packets, 100);
  EXPECT_GT(blocked, 50) << "too few rays blocked by the spheres to mean anything";
  EXPECT_GT(open, 50);
}

// intersect_batch() does intersect()'s work over a batch, the common hits' arithmetic in SIMD
// (each target the machine has): every answer must still be intersect()'s, bit for bit, whatever
// the batch size or the ray's place in it. Camera rays, rays from inside and around the scene in
// every direction (planes hit from both sides and missed), short t_max, and rays starting far
// outside (embree_ray_from_far).
TEST_P(PacketTest, IntersectBatchIsIntersectBitForBit) {
  const RenderScene rs(scene(), 0, options());
  std::vector<Ray> rays = camera_rays(rs, 300);
  const float R = rs.bounds_radius();
  for (int i = 0; i < 300; ++i) {
    const uint64_t h = mix64(uint64_t(i) + 777), g = mix64(h);
    auto unit = [](uint64_t x, int k) { return 2.0f * to_unit_float(uint32_t(x >> (16 * k))) - 1.0f; };
    const float scale = i % 3 == 0 ? 40.0f * R : 1.5f * R;  // a third start beyond 16 R: far rays
    const Vec3f o(unit(h, 0) * scale, unit(h, 1) * scale, unit(h, 2) * scale);
    const Vec3f target(unit(g, 0) * 0.5f * R, unit(g, 1) * 0.5f * R, unit(g, 2) * 0.5f * R);
    const float tmax = i % 4 == 0 ? 0.7f * length(target - o) : std::numeric_limits<float>::infinity();
    rays.push_back({o, normalize(target - o), tmax});
  }
  std::vector<Hit> single(rays.size());
  std::vector<uint8_t> found(rays.size());
  int hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    found[i] = rs.intersect(rays[i], PrimRef{}, &single[i]);
    hits += found[i];
  }
  EXPECT_GT(hits, 200);
  auto bits = [](float x) { return std::bit_cast<uint32_t>(x); };
  for (int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    for (const size_t batch : {size_t(1), size_t(7), size_t(32), size_t(45), kRayBatch}) {
      for (size_t b = 0; b < rays.size(); b += batch) {
        const size_t n = std::min(batch, rays.size() - b);
        RayBatch in;
        for (size_t i = 0; i < n; ++i) {
          const Ray& r = rays[b + i];
          in.ox[i] = r.o.x, in.oy[i] = r.o.y, in.oz[i] = r.o.z;
          in.dx[i] = r.d.x, in.dy[i] = r.d.y, in.dz[i] = r.d.z;
          in.tmax[i] = r.tmax;
          in.skip[i] = 0;
        }
        auto out = std::make_unique<HitBatch>();
        rs.intersect_batch(in, n, out.get());
        for (size_t i = 0; i < n; ++i) {
          const std::string what = "ray " + std::to_string(b + i) + ", batch " + std::to_string(batch);
          const Hit& want = single[b + i];
          switch (out->status[i]) {
            case HitBatch::kMiss: EXPECT_FALSE(found[b + i]) << what; break;
            case HitBatch::kHit: test::expect_identical_hit(found[b + i], want, true, out->hit[i], what); break;
            case HitBatch::kAnswered:
              ASSERT_TRUE(found[b + i]) << what;
              EXPECT_FALSE(want.smooth) << what;
              EXPECT_EQ(bits(out->t[i]), bits(want.t)) << what;
              EXPECT_EQ(std::tuple(bits(out->px[i]), bits(out->py[i]), bits(out->pz[i])),
                        std::tuple(bits(want.p.x), bits(want.p.y), bits(want.p.z))) << what;
              EXPECT_EQ(std::tuple(bits(out->nx[i]), bits(out->ny[i]), bits(out->nz[i])),
                        std::tuple(bits(want.n.x), bits(want.n.y), bits(want.n.z))) << what;
              EXPECT_EQ(std::tuple(bits(out->u[i]), bits(out->v[i])), std::tuple(bits(want.u), bits(want.v))) << what;
              EXPECT_EQ(out->material[i], want.material) << what;
              EXPECT_EQ(out->object[i], rs.source_of(want.prim).object) << what;
              EXPECT_EQ(out->primitive[i], rs.source_of(want.prim).primitive) << what;
              break;
            default: FAIL() << what << ": status " << int(out->status[i]);
          }
        }
      }
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

INSTANTIATE_TEST_SUITE_P(Showcase, PacketTest,
                         ::testing::Combine(::testing::Values("whitted.json", "cornell.json", "bunny.json"),
                                            ::testing::Values(TriangleTest::kWatertight, TriangleTest::kEmbreeRobust)),
                         [](const auto& info) {
                           std::string name = std::string(std::get<0>(info.param));
                           name = name.substr(0, name.find('.'));
                           return name + (std::get<1>(info.param) == TriangleTest::kWatertight ? "Watertight" : "EmbreeRobust");
                         });

}  // namespace
}  // namespace tessera

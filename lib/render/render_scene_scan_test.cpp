// SPDX-License-Identifier: Apache-2.0
// The sphere scan (render_scene_scan.cpp, render/sphere_scan.h) against Embree's BVH: its float
// pre-test must never drop a lane the exact test would hit, on any SIMD target, and a scanned
// scene must answer every packet query bit for bit as the same scene traversed by Embree.
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "render/ray_batch.h"
#include "render/render_scene_internal.h"
#include "render/sampler.h"
#include "render/sphere_roots.h"
#include "render/sphere_scan.h"
#include "render/test_hits.h"
#include "render/test_scenes.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

constexpr int P = RenderScene::kPacket;

// A deterministic stream of floats in [-1, 1).
struct Stream {
  uint64_t state;
  float next() {
    state = mix64(state + 0x9E3779B97F4A7C15ull);
    return 2.0f * to_unit_float(uint32_t(state)) - 1.0f;
  }
  Vec3f vec() { return {next(), next(), next()}; }
  Vec3f unit() {
    for (;;) {
      const Vec3f v = vec();
      const float l = length(v);
      if (l > 0.1f && l <= 1.0f) return v / l;
    }
  }
};

// Rays that graze a sphere: tangent to it at a surface point, then nudged by a few float steps
// towards and away from the centre, so that the exact test's answer flips among them; plus rays
// from the surface itself (leaving it inward and outward) and rays from anywhere around it.
TEST(SphereScan, CandidatesKeepEveryLaneTheExactTestHits) {
  Stream s{7};
  int hits = 0, culled = 0, lanes_tested = 0;
  for (int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    for (int sphere = 0; sphere < 300; ++sphere) {
      const double scale = std::pow(10.0, double(sphere % 7) - 3.0);  // radii 1e-3 .. 1e3
      const Vec3d c = Vec3d(s.vec()) * (50.0 * scale);
      const double r = scale * (0.5 + 0.5 * std::abs(double(s.next())));
      for (int packet = 0; packet < 8; ++packet) {
        alignas(32) float ox[P], oy[P], oz[P], dx[P], dy[P], dz[P], tmax[P];
        alignas(32) int32_t active[P], leaving[P];
        alignas(32) const float tnear[P] = {};
        for (int i = 0; i < P; ++i) {
          const Vec3f n = s.unit();
          const Vec3f p = Vec3f(c + Vec3d(n) * r);  // a surface point (rounded)
          Vec3f o, d;
          leaving[i] = 0;
          switch ((packet + i) % 4) {
            case 0: {  // tangent at p, nudged by -4..4 float steps of the distance
              Vec3f t = normalize(cross(n, s.unit()));
              const float nudge = float((i % 9) - 4) * 0x1p-23f * float(r);
              d = t;
              o = p + n * nudge - t * float(r * (1.0 + 3.0 * std::abs(double(s.next()))));
              break;
            }
            case 1:  // from the surface, inward or outward
              o = p;
              d = i % 2 ? s.unit() : -n + s.unit() * 0.5f;
              leaving[i] = 1;
              break;
            case 2:  // towards the sphere from around it
              o = Vec3f(c) + s.vec() * float(6.0 * r);
              d = Vec3f(c) + s.vec() * float(r) - o;
              break;
            default:  // anywhere, any direction, any length
              o = Vec3f(c) + s.vec() * float(20.0 * r);
              d = s.vec() * float(std::pow(10.0, double(i % 5) - 2.0));
              break;
          }
          ox[i] = o.x, oy[i] = o.y, oz[i] = o.z, dx[i] = d.x, dy[i] = d.y, dz[i] = d.z;
          tmax[i] = std::numeric_limits<float>::infinity();
          active[i] = 1;
        }
        double t[P];
        sphere_roots({ox, oy, oz, dx, dy, dz, tnear, tmax, active, leaving}, c, r, t);
        // The table for exactly these origins: the tightest bound the scan allows.
        double origins = 0;
        for (int i = 0; i < P; ++i) {
          origins = std::max(origins, double(std::abs(ox[i])) + double(std::abs(oy[i])) + double(std::abs(oz[i])));
        }
        ScanTable table;
        add_scan_sphere(&table, c.x, c.y, c.z, r, origins);
        uint32_t near = 0;
        scan_candidates(RayArrays(ox, oy, oz, dx, dy, dz, tmax), table, (1u << P) - 1u, &near);
        for (int i = 0; i < P; ++i) {
          ++lanes_tested;
          if (t[i] >= 0) {
            ++hits;
            EXPECT_TRUE((near >> i) & 1u) << "sphere " << sphere << " lane " << i << ": root " << t[i]
                                          << " but the scan left the lane out";
          } else if (!((near >> i) & 1u)) {
            ++culled;
          }
        }
      }
    }
  }
  hwy::SetSupportedTargetsForTest(0);
  // The test means something only if both answers were common.
  EXPECT_GT(hits, lanes_tested / 5);
  EXPECT_GT(culled, lanes_tested / 5);
}

// A scene of 7 spheres (opaque, mirror, nested glass) over a plane: scanned by default, and the
// same scene traversed by Embree.
std::string seven_spheres() {
  return R"({
    "camera": {"position": [0, 1.6, 6.5], "look_at": [0, 0.9, 0], "vfov_deg": 50},
    "image": {"width": 64, "height": 48, "spp": 1, "max_depth": 6},
    "lights": [{"type": "point", "position": [-4, 6, 5], "intensity": 160}],
    "materials": {
      "c": {"type": "diffuse", "albedo": [0.8, 0.1, 0.1]}, "mi": {"type": "mirror", "reflectance": 0.9},
      "g": {"type": "glass", "ior": 1.5, "transmittance": [0.9, 0.8, 0.7]},
      "h": {"type": "glass", "ior": 1.33, "transmittance": [0.7, 0.9, 0.8]}, "d": {"type": "diffuse", "albedo": [0.2, 0.5, 0.25]}},
    "objects": [
      {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "c"},
      {"type": "sphere", "center": [-1.5, 1, -0.8], "radius": 1, "material": "mi"},
      {"type": "sphere", "center": [0.55, 0.8, 1.4], "radius": 0.8, "material": "g"},
      {"type": "sphere", "center": [0.55, 0.8, 1.4], "radius": 0.4, "material": "h"},
      {"type": "sphere", "center": [2, 0.7, -0.6], "radius": 0.7, "material": "d"},
      {"type": "sphere", "center": [-0.4, 0.3, 2.2], "radius": 0.3, "material": "d"},
      {"type": "sphere", "center": [1.2, 2.2, 0.2], "radius": 0.5, "material": "g"},
      {"type": "sphere", "center": [0, -30, 0], "radius": 29.9, "material": "d"}]
  })";
}

// Packets of camera rays, of rays leaving sphere and plane hits inward and outward, and of rays
// from anywhere in the scene; then shadow rays from the same points to random points: the scan's
// answers are Embree's, bit for bit, every lane, in whole packets and in partly filled ones.
TEST(SphereScan, ScannedSceneAnswersPacketsAsEmbreeDoes) {
  const Scene scene = parse_scene(seven_spheres(), "seven.json");
  const RenderScene scanned(scene, 0);
  RenderOptions embree_options;
  embree_options.spheres = SphereSearch::kEmbree;
  const RenderScene traversed(scene, 0, embree_options);
  ASSERT_TRUE(scanned.scans_spheres());
  ASSERT_FALSE(traversed.scans_spheres());

  Stream s{11};
  std::vector<Ray> rays;
  std::vector<PrimRef> from;
  const auto& cam = scanned.camera();
  for (int i = 0; i < 3000; ++i) {
    const Ray camera{Vec3f(0.0f), normalize(cam.p0 + cam.du * (0.5f + 0.5f * s.next()) + cam.dv * (0.5f + 0.5f * s.next()))};
    rays.push_back(camera);
    from.push_back({});
    Hit h;
    if (scanned.intersect(camera, PrimRef{}, &h)) {
      // Leaving the surface from the hit point itself (exact exclusion, no offset): outward,
      // and inward (into a sphere: the far root only).
      rays.push_back({h.p, normalize(h.n + s.unit() * 0.9f)});
      from.push_back(h.prim);
      rays.push_back({h.p, normalize(-h.n + s.unit() * 0.9f)});
      from.push_back(h.prim);
    }
    rays.push_back({s.vec() * 3.0f + Vec3f(0, 1, 0), s.unit(), i % 3 ? std::numeric_limits<float>::infinity() : 2.0f});
    from.push_back({});
  }
  int hits = 0, blocked = 0, crossed = 0, open = 0;
  for (size_t base = 0; base + P <= rays.size(); base += P) {
    Hit a[P], b[P];
    bool fa[P], fb[P];
    scanned.intersect_packet(&rays[base], &from[base], P, a, fa);
    traversed.intersect_packet(&rays[base], &from[base], P, b, fb);
    Ray shadow[P];
    for (int i = 0; i < P; ++i) {
      test::expect_identical_hit(fb[i], b[i], fa[i], a[i], "ray " + std::to_string(base + i));
      hits += fa[i];
      const Vec3f target = s.vec() * 3.0f + Vec3f(0, 2, 0);
      shadow[i] = {rays[base + i].o, normalize(target - rays[base + i].o), length(target - rays[base + i].o)};
    }
    Rgb ta[P], tb[P];
    scanned.transmittance_packet(shadow, &from[base], P, ta);
    traversed.transmittance_packet(shadow, &from[base], P, tb);
    for (int i = 0; i < P; ++i) {
      const std::string what = "shadow ray " + std::to_string(base + i);
      EXPECT_EQ(std::bit_cast<uint32_t>(ta[i].x), std::bit_cast<uint32_t>(tb[i].x)) << what;
      EXPECT_EQ(std::bit_cast<uint32_t>(ta[i].y), std::bit_cast<uint32_t>(tb[i].y)) << what;
      EXPECT_EQ(std::bit_cast<uint32_t>(ta[i].z), std::bit_cast<uint32_t>(tb[i].z)) << what;
      const bool zero = tb[i].x == 0 && tb[i].y == 0 && tb[i].z == 0, one = tb[i].x == 1 && tb[i].y == 1 && tb[i].z == 1;
      (zero ? blocked : one ? open : crossed)++;
    }
    // The same rays as a partly filled packet (1..7 lanes), scanned too.
    const int k = 1 + int(base / P) % (P - 1);
    scanned.intersect_packet(&rays[base], &from[base], k, a, fa);
    traversed.intersect_packet(&rays[base], &from[base], k, b, fb);
    scanned.transmittance_packet(shadow, &from[base], k, ta);
    traversed.transmittance_packet(shadow, &from[base], k, tb);
    for (int i = 0; i < k; ++i) {
      const std::string what = "ray " + std::to_string(base + i) + " of " + std::to_string(k);
      test::expect_identical_hit(fb[i], b[i], fa[i], a[i], what);
      EXPECT_EQ(std::bit_cast<uint32_t>(ta[i].x), std::bit_cast<uint32_t>(tb[i].x)) << what;
      EXPECT_EQ(std::bit_cast<uint32_t>(ta[i].z), std::bit_cast<uint32_t>(tb[i].z)) << what;
    }
  }
  // Every kind of answer must have come up often enough to mean something.
  EXPECT_GT(hits, 4000);
  EXPECT_GT(blocked, 200);
  EXPECT_GT(open, 1000);
  EXPECT_GT(crossed, 100) << "too few shadow rays through glass";
}

// Which scenes are scanned: at most kScanSpheres spheres and no triangles, unless told not to.
TEST(SphereScan, OnlySmallSceneWithoutTrianglesIsScanned) {
  EXPECT_TRUE(RenderScene(parse_scene(test::whitted_like(8, 8, 1), "w.json"), 0).scans_spheres());
  EXPECT_FALSE(RenderScene(load_scene(std::string(TESSERA_SOURCE_DIR) + "/scenes/bunny.json"), 0).scans_spheres());
  std::string many = seven_spheres();
  const std::string extra = R"({"type": "sphere", "center": [3, 1, 1], "radius": 0.2, "material": "d"},)";
  many.insert(many.find("{\"type\": \"sphere\""), extra + extra);  // 9 spheres
  EXPECT_FALSE(RenderScene(parse_scene(many, "nine.json"), 0).scans_spheres());
}

}  // namespace
}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "render/sphere.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <bit>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "render/sphere_roots.h"

namespace tessera {
namespace {

TEST(Sphere, HeadOnHitHasBothRoots) {
  double t[2];
  ASSERT_EQ(intersect_sphere({0, 0, -5}, {0, 0, 1}, {0, 0, 0}, 1.0, t), 2);
  EXPECT_DOUBLE_EQ(t[0], 4.0);
  EXPECT_DOUBLE_EQ(t[1], 6.0);
}

TEST(Sphere, MissReturnsNoRoots) {
  double t[2];
  EXPECT_EQ(intersect_sphere({0, 2, -5}, {0, 0, 1}, {0, 0, 0}, 1.0, t), 0);
}

TEST(Sphere, RayStartingInsideHasOneNegativeAndOnePositiveRoot) {
  double t[2];
  ASSERT_EQ(intersect_sphere({0, 0, 0.25}, {0, 0, 1}, {0, 0, 0}, 1.0, t), 2);
  EXPECT_DOUBLE_EQ(t[0], -1.25);
  EXPECT_DOUBLE_EQ(t[1], 0.75);
}

TEST(Sphere, GrazingRayTouchesAtOnePoint) {
  double t[2];
  ASSERT_EQ(intersect_sphere({-5, 1, 0}, {1, 0, 0}, {0, 0, 0}, 1.0, t), 2);
  EXPECT_NEAR(t[0], 5.0, 1e-7);
  EXPECT_NEAR(t[1], 5.0, 1e-7);
  EXPECT_EQ(intersect_sphere({-5, std::nextafter(1.0, 2.0), 0}, {1, 0, 0}, {0, 0, 0}, 1.0, t), 0);
}

TEST(Sphere, TinyFarSphereIsHitAccurately) {
  // radius 1e-3 at distance 1e4: the naive b^2 - 4ac loses every digit of the discriminant.
  double t[2];
  ASSERT_EQ(intersect_sphere({0, 0, 0}, {0, 0, 1}, {0, 0, 1e4}, 1e-3, t), 2);
  EXPECT_NEAR(t[0], 1e4 - 1e-3, 1e-9);
  EXPECT_NEAR(t[1], 1e4 + 1e-3, 1e-9);
  // Just inside the silhouette edge it still hits, just outside it misses.
  const Vec3d d_in = normalize(Vec3d{0.999e-3, 0, 1e4});
  const Vec3d d_out = normalize(Vec3d{1.001e-3, 0, 1e4});
  EXPECT_EQ(intersect_sphere({0, 0, 0}, d_in, {0, 0, 1e4}, 1e-3, t), 2);
  EXPECT_EQ(intersect_sphere({0, 0, 0}, d_out, {0, 0, 1e4}, 1e-3, t), 0);
}

TEST(Sphere, HugeSphereSeenFromJustAboveItsSurface) {
  // A ground sphere of radius 1e4 and an eye 1e-3 above it: looking straight down hits at 1e-3.
  double t[2];
  ASSERT_EQ(intersect_sphere({0, 1e-3, 0}, {0, -1, 0}, {0, -1e4, 0}, 1e4, t), 2);
  // The input itself is only known to double precision at the scale of 1e4 (o - c = 10000.001
  // rounds by ~1e-12): that is the bound. In float the same case would be off by ~1e-3.
  EXPECT_NEAR(t[0], 1e-3, 4e-12);
  EXPECT_NEAR(t[1], 2e4 + 1e-3, 1e-9);
}

TEST(Sphere, RootsSatisfyTheSphereEquation) {
  // Randomized: every returned root lies on the sphere to double precision relative to scale.
  uint64_t state = 12345;
  auto rnd = [&] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) * 0x1p-53 * 2.0 - 1.0;
  };
  for (int i = 0; i < 10000; ++i) {
    const double scale = std::pow(10.0, 6.0 * rnd());
    const Vec3d c{rnd() * scale, rnd() * scale, rnd() * scale};
    const double r = scale * (0.01 + std::abs(rnd()));
    const Vec3d o = c + Vec3d{rnd(), rnd(), rnd()} * (3 * r);
    const Vec3d d = normalize(c + Vec3d{rnd(), rnd(), rnd()} * r - o);
    double t[2];
    if (intersect_sphere(o, d, c, r, t) == 0) continue;
    for (double root : t) {
      const double dist = length(o + d * root - c);
      EXPECT_NEAR(dist, r, 1e-9 * (r + length(o - c))) << "case " << i;
    }
  }
}


// The rule of the sphere geometry's callbacks, from intersect_sphere: the first root whose float
// lies in (tnear, tfar); a ray leaving the sphere meets it only inward, at its far root.
double reference_root(const Vec3d& o, const Vec3d& d, const Vec3d& c, double r, float tnear, float tfar,
                      bool leaving) {
  int first = 0;
  if (leaving) {
    if (dot(d, o - c) >= 0) return -1;
    first = 1;
  }
  double t[2];
  if (intersect_sphere(o, d, c, r, t) == 0) return -1;
  for (int i = first; i < 2; ++i) {
    if (float(t[i]) > tnear && float(t[i]) < tfar) return t[i];
  }
  return -1;
}

// Every lane of sphere_roots on every SIMD target this machine runs is bit for bit the scalar
// rule, on rays that hit, miss, graze, start on the surface (leaving inward and outward), start
// at the centre, and see the roots cut by tnear and tfar.
TEST(SphereRoots, EveryLaneEqualsTheScalarRuleOnEveryTarget) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  const Vec3d center(0.5, -0.25, -3.0);
  const double radius = 1.25;
  const int kPackets = 3000;
  std::vector<float> v(size_t(kPackets) * 8 * 8);
  std::vector<int32_t> active(size_t(kPackets) * 8), leaving(size_t(kPackets) * 8);
  for (int p = 0; p < kPackets; ++p) {
    for (int i = 0; i < 8; ++i) {
      const size_t k = size_t(p) * 8 + size_t(i);
      Vec3f o(u(rng) * 4, u(rng) * 4, u(rng) * 4);
      Vec3f aim = Vec3f(center) + Vec3f(u(rng), u(rng), u(rng)) * float(radius) * 1.1f;
      const int kind = int(k % 5);
      if (kind == 1 || kind == 2) {  // on the surface, leaving it
        const Vec3f n = normalize(Vec3f(u(rng), u(rng), u(rng)));
        o = Vec3f(center + Vec3d(n) * radius);
        leaving[k] = 1;
      } else if (kind == 3) {
        o = Vec3f(center);  // at the centre
      } else if (kind == 4) {  // grazing: aimed at a point on the silhouette
        const Vec3f n = normalize(cross(Vec3f(center) - o, Vec3f(u(rng), u(rng), u(rng))));
        aim = Vec3f(center) + n * float(radius);
      }
      Vec3f d = normalize(aim - o);
      if (!(length(aim - o) > 0.0f)) d = Vec3f(0, 0, 1);
      const float tnear = k % 3 == 0 ? 0.5f : 0.0f;
      const float tfar = k % 7 == 0 ? 2.0f : std::numeric_limits<float>::infinity();
      const float f[8] = {o.x, o.y, o.z, d.x, d.y, d.z, tnear, tfar};
      for (int c = 0; c < 8; ++c) v[(size_t(p) * 8 + size_t(c)) * 8 + size_t(i)] = f[c];
      active[k] = k % 11 == 0 ? 0 : 1;
    }
  }
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    size_t hits = 0, leaving_hits = 0;
    for (int p = 0; p < kPackets; ++p) {
      const float* a = &v[size_t(p) * 64];
      const SphereLanes lanes{a, a + 8, a + 16, a + 24, a + 32, a + 40, a + 48, a + 56,
                              &active[size_t(p) * 8], &leaving[size_t(p) * 8]};
      double t[kSphereLanes];
      sphere_roots(lanes, center, radius, t);
      for (int i = 0; i < 8; ++i) {
        const size_t k = size_t(p) * 8 + size_t(i);
        const double want =
            active[k] ? reference_root({a[i], a[8 + i], a[16 + i]}, {a[24 + i], a[32 + i], a[40 + i]}, center, radius,
                                       a[48 + i], a[56 + i], leaving[k] != 0)
                      : -1.0;
        ASSERT_EQ(std::bit_cast<uint64_t>(t[i]), std::bit_cast<uint64_t>(want)) << "packet " << p << " lane " << i;
        hits += want >= 0;
        leaving_hits += want >= 0 && leaving[k];
      }
    }
    EXPECT_GT(hits, size_t(kPackets) * 2) << "too few hits to mean anything";
    EXPECT_GT(leaving_hits, size_t(kPackets) / 4) << "too few inward rays from the surface";
  }
  hwy::SetSupportedTargetsForTest(0);
}

}  // namespace
}  // namespace tessera

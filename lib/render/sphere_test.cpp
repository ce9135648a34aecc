#include "render/sphere.h"

#include <gtest/gtest.h>

#include <cmath>

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

}  // namespace
}  // namespace tessera

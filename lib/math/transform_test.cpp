#include "math/transform.h"

#include <gtest/gtest.h>

namespace tessera {
namespace {

void expect_near(const Vec3d& a, const Vec3d& b, double tol = 1e-12) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

TEST(Transform, RotationOrderIsXThenYThenZ) {
  // Rotating +Y by 90 deg about X gives +Z; then 90 deg about Y sends +Z to +X.
  const Transform r = Transform::rotate_xyz_deg({90, 90, 0});
  expect_near(r.vector({0, 1, 0}), {1, 0, 0});
}

TEST(Transform, CompositionAppliesRightFirst) {
  const Transform t = Transform::translate({1, 2, 3}) * Transform::scale({2, 2, 2});
  expect_near(t.point({1, 1, 1}), {3, 4, 5});
  expect_near(t.vector({1, 1, 1}), {2, 2, 2});
}

TEST(Transform, NormalsStayPerpendicularUnderNonUniformScale) {
  const Transform s = Transform::rotate_xyz_deg({10, 20, 30}) * Transform::scale({1, 5, 0.2});
  const Vec3d a{1, 1, 0}, b{0, 1, 1};
  const Vec3d n = cross(a, b);
  const Vec3d tn = s.normal(n);
  EXPECT_NEAR(dot(tn, s.vector(a)), 0.0, 1e-12);
  EXPECT_NEAR(dot(tn, s.vector(b)), 0.0, 1e-12);
  EXPECT_GT(dot(normalize(tn), normalize(cross(s.vector(a), s.vector(b)))), 0.999999);
}

TEST(Transform, MirroringKeepsNormalOrientationConsistentWithWinding) {
  const Transform m = Transform::scale({-1, 1, 1});
  const Vec3d a{1, 0, 0}, b{0, 1, 0};
  // The transformed triangle's winding normal must agree with the transformed normal.
  const Vec3d winding = cross(m.vector(a), m.vector(b));
  EXPECT_LT(dot(m.normal(cross(a, b)), winding), 0.0);  // mirroring flips winding...
  EXPECT_NEAR(std::abs(dot(normalize(m.normal({0, 0, 1})), {0, 0, 1})), 1.0, 1e-12);
}

}  // namespace
}  // namespace tessera

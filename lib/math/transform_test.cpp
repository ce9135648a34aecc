// SPDX-License-Identifier: Apache-2.0
#include "math/transform.h"

#include <gtest/gtest.h>

#include <cmath>

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

// Row-major entries in, column-major Matrix4 out (glTF's layout).
Matrix4 rows(const std::array<double, 16>& r) {
  Matrix4 m;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) m.at(i, j) = r[size_t(4 * i + j)];
  }
  return m;
}

void expect_rows(const Matrix4& m, const std::array<double, 16>& r) {
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) EXPECT_EQ(m.at(i, j), r[size_t(4 * i + j)]) << "row " << i << ", column " << j;
  }
}

TEST(Matrix4, IsColumnMajorAsGltfWritesIt) {
  Matrix4 m;
  m.m = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
  EXPECT_EQ(m.at(1, 0), 2);
  EXPECT_EQ(m.at(0, 1), 5);
  EXPECT_EQ(m.column(3).x, 13);
  EXPECT_EQ(m.column(3).z, 15);
  const std::array<double, 12> a = m.affine();  // row-major, bottom row dropped
  const std::array<double, 12> want{1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15};
  EXPECT_EQ(a, want);
}

TEST(Matrix4, ProductMatchesHandComputedValues) {
  const Matrix4 a = rows({1, 2, 0, 3, 0, 1, 4, 5, 2, 0, 1, 6, 0, 0, 0, 1});
  const Matrix4 b = rows({2, 0, 1, 1, 1, 3, 0, 2, 0, 1, 1, 0, 0, 0, 0, 1});
  expect_rows(a * b, {4, 6, 1, 8, 1, 7, 4, 7, 4, 1, 3, 8, 0, 0, 0, 1});
  expect_rows(b * a, {4, 4, 1, 13, 1, 5, 12, 20, 2, 1, 5, 11, 0, 0, 0, 1});
}

TEST(Matrix4, ProductKeepsTheBottomRowsTerms) {
  // A bottom row other than 0 0 0 1 takes part: (a b)_00 = 1 2 + 2 1 + 0 0 + 3 1.
  const Matrix4 a = rows({1, 2, 0, 3, 0, 1, 4, 5, 2, 0, 1, 6, 0, 0, 0, 1});
  const Matrix4 b = rows({2, 0, 1, 1, 1, 3, 0, 2, 0, 1, 1, 0, 1, 0, 0, 1});
  expect_rows(a * b, {7, 6, 1, 8, 6, 7, 4, 7, 10, 1, 3, 8, 1, 0, 0, 1});
  // Through the identity a -0 entry becomes +0 (1 (-0) + 0 1 + 0 0 + 0 0).
  Matrix4 z;
  z.at(0, 1) = -0.0;
  EXPECT_TRUE(std::signbit(z.at(0, 1)));
  EXPECT_FALSE(std::signbit((Matrix4() * z).at(0, 1)));
}

TEST(Matrix4, TrsIsTranslateTimesRotateTimesScale) {
  // (0, 0, 2, 0) normalizes to a half turn about Z: R = diag(-1, -1, 1); columns scaled by s.
  const Matrix4 m = trs_matrix({{1, 2, 3}, {0, 0, 2, 0}, {2, 3, 4}});
  expect_rows(m, {-2, 0, 0, 1, 0, -3, 0, 2, 0, 0, 4, 3, 0, 0, 0, 1});
  // (1, 0, 0, 1): a quarter turn about X, +Y to +Z and +Z to -Y.
  const Matrix4 r = trs_matrix({{0, 0, 0}, {1, 0, 0, 1}, {1, 1, 1}});
  expect_near(r.column(1), {0, 0, 1}, 1e-15);
  expect_near(r.column(2), {0, -1, 0}, 1e-15);
  expect_near(r.column(3), {0, 0, 0}, 0);
  // The identity quaternion and unit scale leave the translation alone.
  expect_rows(trs_matrix({{5, -6, 7}, {0, 0, 0, 1}, {1, 1, 1}}), {1, 0, 0, 5, 0, 1, 0, -6, 0, 0, 1, 7, 0, 0, 0, 1});
}

}  // namespace
}  // namespace tessera

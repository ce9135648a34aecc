// SPDX-License-Identifier: Apache-2.0
// Affine transform of points, vectors and normals, in double precision (world space); and the
// 4x4 matrices and translation-rotation-scale triples glTF nodes are written in.
#pragma once

#include <array>

#include "math/vec3.h"

namespace tessera {

// Row-major 3x4 affine matrix: p' = M p + t.
class Transform {
 public:
  Transform() = default;

  static Transform translate(const Vec3d& t);
  static Transform scale(const Vec3d& s);
  // Rotation by Euler angles in degrees, applied X first, then Y, then Z (R = Rz Ry Rx).
  static Transform rotate_xyz_deg(const Vec3d& deg);
  // A general affine matrix, row-major 3x4: p' = M p + t (m[4 i + j] = M_ij, m[4 i + 3] = t_i).
  static Transform affine(const std::array<double, 12>& m);
  // Composition: (a * b)(p) == a(b(p)).
  friend Transform operator*(const Transform& a, const Transform& b);

  Vec3d point(const Vec3d& p) const;
  Vec3d vector(const Vec3d& v) const;
  // Normals transform by the inverse transpose, so non-uniform scale keeps them perpendicular.
  Vec3d normal(const Vec3d& n) const;
  double determinant() const;

 private:
  std::array<std::array<double, 3>, 3> m_{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  Vec3d t_{0, 0, 0};
};

// Column-major 4x4, as glTF writes matrices: m[4 * column + row].
// glTF node transforms are composed as these full 4x4 products, not as Transform's 3x4
// composition: the products keep the bottom row's terms (+-0 for an affine matrix, which can
// turn a -0 entry into +0), so the two can differ in the sign of a zero (and, for a node matrix
// whose bottom row is not 0 0 0 1, in more), and glTF scenes must keep the transforms they had.
struct Matrix4 {
  std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double& at(int row, int col) { return m[size_t(4 * col + row)]; }
  double at(int row, int col) const { return m[size_t(4 * col + row)]; }
  Vec3d column(int c) const { return {at(0, c), at(1, c), at(2, c)}; }
  // The top three rows, row-major, as Transform::affine takes them.
  std::array<double, 12> affine() const;
};

// Every entry the sum of its four products, added left to right.
Matrix4 operator*(const Matrix4& a, const Matrix4& b);

// A glTF node's local transform: translation, rotation quaternion (x, y, z, w), scale.
struct Trs {
  Vec3d t{0, 0, 0};
  std::array<double, 4> q{0, 0, 0, 1};  // x, y, z, w
  Vec3d s{1, 1, 1};
};

// T * R * S. The quaternion is normalized first (a zero one is used as it is): animation
// outputs need not be unit.
Matrix4 trs_matrix(const Trs& v);

}  // namespace tessera

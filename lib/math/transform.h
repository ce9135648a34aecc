// Affine transform of points, vectors and normals, in double precision (world space).
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

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "math/transform.h"

#include <cmath>
#include <numbers>

namespace tessera {

Transform Transform::translate(const Vec3d& t) {
  Transform r;
  r.t_ = t;
  return r;
}

Transform Transform::scale(const Vec3d& s) {
  Transform r;
  r.m_ = {{{s.x, 0, 0}, {0, s.y, 0}, {0, 0, s.z}}};
  return r;
}

Transform Transform::rotate_xyz_deg(const Vec3d& deg) {
  const double k = std::numbers::pi / 180.0;
  const double cx = std::cos(deg.x * k), sx = std::sin(deg.x * k);
  const double cy = std::cos(deg.y * k), sy = std::sin(deg.y * k);
  const double cz = std::cos(deg.z * k), sz = std::sin(deg.z * k);
  Transform rx, ry, rz;
  rx.m_ = {{{1, 0, 0}, {0, cx, -sx}, {0, sx, cx}}};
  ry.m_ = {{{cy, 0, sy}, {0, 1, 0}, {-sy, 0, cy}}};
  rz.m_ = {{{cz, -sz, 0}, {sz, cz, 0}, {0, 0, 1}}};
  return rz * ry * rx;
}

Transform Transform::affine(const std::array<double, 12>& m) {
  Transform r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r.m_[i][j] = m[size_t(4 * i + j)];
  }
  r.t_ = {m[3], m[7], m[11]};
  return r;
}

Transform operator*(const Transform& a, const Transform& b) {
  Transform r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      r.m_[i][j] = a.m_[i][0] * b.m_[0][j] + a.m_[i][1] * b.m_[1][j] + a.m_[i][2] * b.m_[2][j];
    }
  }
  r.t_ = a.point(b.t_);
  return r;
}

Vec3d Transform::vector(const Vec3d& v) const {
  return {m_[0][0] * v.x + m_[0][1] * v.y + m_[0][2] * v.z,
          m_[1][0] * v.x + m_[1][1] * v.y + m_[1][2] * v.z,
          m_[2][0] * v.x + m_[2][1] * v.y + m_[2][2] * v.z};
}

Vec3d Transform::point(const Vec3d& p) const { return vector(p) + t_; }

double Transform::determinant() const {
  return m_[0][0] * (m_[1][1] * m_[2][2] - m_[1][2] * m_[2][1]) -
         m_[0][1] * (m_[1][0] * m_[2][2] - m_[1][2] * m_[2][0]) +
         m_[0][2] * (m_[1][0] * m_[2][1] - m_[1][1] * m_[2][0]);
}

Vec3d Transform::normal(const Vec3d& n) const {
  // Cofactor matrix = det * inverse transpose; the scale factor does not matter for a normal,
  // but the sign does: a mirroring transform (det < 0) flips the cofactor's orientation.
  const auto& m = m_;
  const double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
  const double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
  const double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
  const double c10 = m[0][2] * m[2][1] - m[0][1] * m[2][2];
  const double c11 = m[0][0] * m[2][2] - m[0][2] * m[2][0];
  const double c12 = m[0][1] * m[2][0] - m[0][0] * m[2][1];
  const double c20 = m[0][1] * m[1][2] - m[0][2] * m[1][1];
  const double c21 = m[0][2] * m[1][0] - m[0][0] * m[1][2];
  const double c22 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
  Vec3d r{c00 * n.x + c01 * n.y + c02 * n.z, c10 * n.x + c11 * n.y + c12 * n.z,
          c20 * n.x + c21 * n.y + c22 * n.z};
  return determinant() < 0 ? -r : r;
}

std::array<double, 12> Matrix4::affine() const {
  std::array<double, 12> a{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 4; ++j) a[size_t(4 * i + j)] = at(i, j);
  }
  return a;
}

Matrix4 operator*(const Matrix4& a, const Matrix4& b) {
  Matrix4 r;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      r.at(i, j) = a.at(i, 0) * b.at(0, j) + a.at(i, 1) * b.at(1, j) + a.at(i, 2) * b.at(2, j) + a.at(i, 3) * b.at(3, j);
    }
  }
  return r;
}

Matrix4 trs_matrix(const Trs& v) {
  double x = v.q[0], y = v.q[1], z = v.q[2], w = v.q[3];
  const double n = std::sqrt(x * x + y * y + z * z + w * w);
  if (n > 0) { x /= n; y /= n; z /= n; w /= n; }  // animation outputs need not be unit
  Matrix4 r;
  const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  const double S[3] = {v.s.x, v.s.y, v.s.z};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r.at(i, j) = R[i][j] * S[j];
  }
  r.at(0, 3) = v.t.x;
  r.at(1, 3) = v.t.y;
  r.at(2, 3) = v.t.z;
  return r;
}

}  // namespace tessera

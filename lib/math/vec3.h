// SPDX-License-Identifier: Apache-2.0
// Small 3-vector value type, templated so the scene can stay in double (world space)
// while the renderer works in float (camera-relative space).
#pragma once

#include <algorithm>
#include <cmath>
#include <ostream>

namespace tessera {

template <typename T>
struct Vec3 {
  T x{}, y{}, z{};

  constexpr Vec3() = default;
  constexpr Vec3(T x_, T y_, T z_) : x(x_), y(y_), z(z_) {}
  constexpr explicit Vec3(T v) : x(v), y(v), z(v) {}
  template <typename U>
  constexpr explicit Vec3(const Vec3<U>& o) : x(T(o.x)), y(T(o.y)), z(T(o.z)) {}

  constexpr T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  T& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }

  constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  constexpr Vec3 operator*(const Vec3& o) const { return {x * o.x, y * o.y, z * o.z}; }
  constexpr Vec3 operator/(const Vec3& o) const { return {x / o.x, y / o.y, z / o.z}; }
  constexpr Vec3 operator*(T s) const { return {x * s, y * s, z * s}; }
  constexpr Vec3 operator/(T s) const { return {x / s, y / s, z / s}; }
  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
  Vec3& operator-=(const Vec3& o) { x -= o.x; y -= o.y; z -= o.z; return *this; }
  Vec3& operator*=(const Vec3& o) { x *= o.x; y *= o.y; z *= o.z; return *this; }
  Vec3& operator*=(T s) { x *= s; y *= s; z *= s; return *this; }
  constexpr bool operator==(const Vec3&) const = default;
};

template <typename T>
constexpr Vec3<T> operator*(T s, const Vec3<T>& v) { return v * s; }

template <typename T>
constexpr T dot(const Vec3<T>& a, const Vec3<T>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

template <typename T>
constexpr Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

template <typename T>
inline T length(const Vec3<T>& v) { return std::sqrt(dot(v, v)); }

template <typename T>
inline Vec3<T> normalize(const Vec3<T>& v) { return v / length(v); }

template <typename T>
inline Vec3<T> abs(const Vec3<T>& v) { return {std::abs(v.x), std::abs(v.y), std::abs(v.z)}; }

template <typename T>
inline T max_component(const Vec3<T>& v) { return std::max(v.x, std::max(v.y, v.z)); }

template <typename T>
inline Vec3<T> vmin(const Vec3<T>& a, const Vec3<T>& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
template <typename T>
inline Vec3<T> vmax(const Vec3<T>& a, const Vec3<T>& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}

template <typename T>
inline bool is_finite(const Vec3<T>& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

template <typename T>
constexpr Vec3<T> lerp(const Vec3<T>& a, const Vec3<T>& b, T t) { return a * (T(1) - t) + b * t; }

template <typename T>
std::ostream& operator<<(std::ostream& os, const Vec3<T>& v) {
  return os << '(' << v.x << ", " << v.y << ", " << v.z << ')';
}

using Vec3f = Vec3<float>;
using Vec3d = Vec3<double>;
// Linear RGB radiance, HDR: never clamped before tone mapping.
using Rgb = Vec3<float>;

// Builds an orthonormal basis around unit vector n (Duff et al. 2017, "Building an
// Orthonormal Basis, Revisited"): branchless and free of the singularity of the naive cross product.
template <typename T>
inline void orthonormal_basis(const Vec3<T>& n, Vec3<T>& b1, Vec3<T>& b2) {
  const T sign = std::copysign(T(1), n.z);
  const T a = T(-1) / (sign + n.z);
  const T b = n.x * n.y * a;
  b1 = {T(1) + sign * n.x * n.x * a, sign * b, -sign * n.x};
  b2 = {b, sign + n.y * n.y * a, -n.y};
}

}  // namespace tessera

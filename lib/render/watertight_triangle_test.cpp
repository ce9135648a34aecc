// SPDX-License-Identifier: Apache-2.0
#include "render/watertight_triangle.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace tessera {
namespace {

bool hit(const Vec3f& o, const Vec3f& d, const Vec3f& a, const Vec3f& b, const Vec3f& c, TriangleHit* h,
         float tnear = 0.0f, float tfar = std::numeric_limits<float>::infinity()) {
  return intersect_triangle_watertight(o, ray_shear(d), a, b, c, tnear, tfar, h);
}

// Moeller-Trumbore in double: an independent reference away from the boundaries.
bool reference(const Vec3f& of, const Vec3f& df, const Vec3f& af, const Vec3f& bf, const Vec3f& cf, double* t,
               double* u, double* v) {
  const Vec3d o(of), d(df), a(af), b(bf), c(cf);
  const Vec3d e1 = b - a, e2 = c - a, p = cross(d, e2);
  const double det = dot(e1, p);
  if (det == 0) return false;
  const Vec3d s = o - a, q = cross(s, e1);
  *u = dot(s, p) / det;
  *v = dot(d, q) / det;
  *t = dot(e2, q) / det;
  return *u >= 0 && *v >= 0 && *u + *v <= 1 && *t >= 0;
}

TEST(WatertightTriangle, AgreesWithDoubleMoellerTrumboreAwayFromEdges) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> x(-10, 10);
  int compared = 0;
  for (int i = 0; i < 100000; ++i) {
    const Vec3f a{x(rng), x(rng), x(rng)}, b{x(rng), x(rng), x(rng)}, c{x(rng), x(rng), x(rng)};
    const Vec3f o{x(rng), x(rng), x(rng)};
    const Vec3f d = normalize(Vec3f{x(rng), x(rng), x(rng)});
    double t = 0, u = 0, v = 0;
    const bool ref = reference(o, d, a, b, c, &t, &u, &v);
    // Skip rays within 1e-4 (barycentric) of an edge: there rounding may decide either way.
    if (std::min({u, v, 1 - u - v}) > -1e-4 && std::min({u, v, 1 - u - v}) < 1e-4) continue;
    if (t > -1e-4 && t < 1e-4) continue;
    TriangleHit h;
    ASSERT_EQ(hit(o, d, a, b, c, &h), ref) << "ray " << i;
    if (!ref) continue;
    ++compared;
    EXPECT_NEAR(h.t, t, 1e-4 * (1 + t));
    EXPECT_NEAR(h.u, u, 1e-4);
    EXPECT_NEAR(h.v, v, 1e-4);
  }
  EXPECT_GT(compared, 1000);
}

TEST(WatertightTriangle, BothSidesAndBoundariesAreHit) {
  const Vec3f a{0, 0, 0}, b{1, 0, 0}, c{0, 1, 0};
  TriangleHit h;
  // From the front and from the back.
  ASSERT_TRUE(hit({0.25f, 0.25f, 1}, {0, 0, -1}, a, b, c, &h));
  EXPECT_EQ(h.t, 1.0f);
  EXPECT_EQ(h.u, 0.25f);
  EXPECT_EQ(h.v, 0.25f);
  EXPECT_TRUE(hit({0.25f, 0.25f, -1}, {0, 0, 1}, a, b, c, &h));
  // Exactly at a vertex and exactly on an edge: included.
  EXPECT_TRUE(hit({0, 0, 1}, {0, 0, -1}, a, b, c, &h));
  EXPECT_TRUE(hit({1, 0, 1}, {0, 0, -1}, a, b, c, &h));
  EXPECT_TRUE(hit({0.5f, 0.5f, 1}, {0, 0, -1}, a, b, c, &h));
  // Just outside the hypotenuse: excluded.
  EXPECT_FALSE(hit({0.5f, std::nextafter(0.5f, 1.0f), 1}, {0, 0, -1}, a, b, c, &h));
  // The t range is inclusive at both ends and excludes everything outside it.
  EXPECT_TRUE(hit({0.25f, 0.25f, 1}, {0, 0, -1}, a, b, c, &h, 1.0f, 1.0f));
  EXPECT_FALSE(hit({0.25f, 0.25f, 1}, {0, 0, -1}, a, b, c, &h, 0.0f, std::nextafter(1.0f, 0.0f)));
  EXPECT_FALSE(hit({0.25f, 0.25f, 1}, {0, 0, 1}, a, b, c, &h));  // behind the origin
}

TEST(WatertightTriangle, DegenerateAndNonFiniteInputMisses) {
  TriangleHit h;
  const Vec3f d{0, 0, -1};
  // Zero area (collinear), a ray in the triangle's plane, NaN and infinite vertices.
  EXPECT_FALSE(hit({0.5f, 0, 1}, d, {0, 0, 0}, {1, 0, 0}, {2, 0, 0}, &h));
  EXPECT_FALSE(hit({-1, 0.25f, 0}, {1, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, &h));
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(hit({0.25f, 0.25f, 1}, d, {nan, 0, 0}, {1, 0, 0}, {0, 1, 0}, &h));
  EXPECT_FALSE(hit({0.25f, 0.25f, 1}, d, {0, 0, 0}, {inf, 0, 0}, {0, 1, 0}, &h));
}

// The property the test exists for: rays aimed exactly at the shared vertex of a closed fan, or
// at points of its shared edges, are accepted by at least one triangle of the fan. Fans are
// random (uneven angles, off-plane rim) and far from the origin, where float rounding is coarse.
TEST(WatertightTriangle, FansAreClosedAtTheirVertexAndEdges) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(0, 1);
  int rays = 0, misses = 0;
  for (int fan = 0; fan < 2000; ++fan) {
    const Vec3f center = Vec3f{unit(rng), unit(rng), unit(rng)} * 2000.0f - Vec3f(1000.0f);
    const int k = 4 + int(unit(rng) * 5);  // angles in [0.5, 1] of their sum: each below pi
    std::vector<float> angle(static_cast<size_t>(k));
    float sum = 0;
    for (float& a : angle) sum += (a = 0.5f + 0.5f * unit(rng));
    std::vector<Vec3f> rim;
    float acc = 0;
    for (float a : angle) {
      acc += a / sum * 6.2831853f;
      const float r = 0.5f + unit(rng);
      rim.push_back(center + Vec3f{r * std::cos(acc), r * std::sin(acc), 0.3f * (unit(rng) - 0.5f)});
    }
    auto covered = [&](const Vec3f& o, const Vec3f& d) {
      const RayShear s = ray_shear(d);
      TriangleHit h;
      for (int i = 0; i < k; ++i) {
        const float inf = std::numeric_limits<float>::infinity();
        if (intersect_triangle_watertight(o, s, center, rim[size_t(i)], rim[size_t((i + 1) % k)], 0, inf, &h)) {
          return true;
        }
      }
      return false;
    };
    for (int j = 0; j < 16; ++j) {
      // Mostly from above, tilted up to ~35 degrees: every fan triangle faces the ray.
      const Vec3f d = normalize(Vec3f{0.7f * (unit(rng) - 0.5f), 0.7f * (unit(rng) - 0.5f), -1.0f});
      const Vec3f at_vertex = center;
      const Vec3f& spoke = rim[size_t(j % k)];
      const Vec3f at_edge = center + (spoke - center) * (0.9f * unit(rng));  // inner 90%: interior
      for (const Vec3f& target : {at_vertex, at_edge}) {
        ++rays;
        const bool ok = covered(target - d * 10.0f, d);
        misses += !ok;
        if (!ok) ADD_FAILURE() << "fan " << fan << " ray " << j << " target " << target.x << " " << target.y << " " << target.z << (&target == &at_vertex ? " (vertex)" : " (edge)");
      }
    }
  }
  EXPECT_EQ(misses, 0) << "of " << rays << " rays";
}

}  // namespace
}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "render/fresnel.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tessera {
namespace {

TEST(Fresnel, NormalIncidenceMatchesClosedForm) {
  float ct;
  const float n = 1.5f;
  const float r0 = ((n - 1) / (n + 1)) * ((n - 1) / (n + 1));
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.0f, n, &ct), r0, 1e-7f);
  EXPECT_NEAR(fresnel_dielectric(1.0f, n, 1.0f, &ct), r0, 1e-7f);  // symmetric at normal incidence
}

TEST(Fresnel, IndexOneReflectsNothing) {
  float ct;
  for (float c = 0.05f; c <= 1.0f; c += 0.05f) EXPECT_EQ(fresnel_dielectric(c, 1.0f, 1.0f, &ct), 0.0f);
}

TEST(Fresnel, TotalInternalReflectionBeyondTheCriticalAngle) {
  const float n = 1.5f;
  const float critical_cos = std::cos(std::asin(1.0f / n));
  float ct;
  EXPECT_EQ(fresnel_dielectric(critical_cos * 0.99f, n, 1.0f, &ct), 1.0f);
  EXPECT_LT(fresnel_dielectric(critical_cos * 1.01f, n, 1.0f, &ct), 1.0f);
}

TEST(Fresnel, BrewsterAngleZeroesThePComponent) {
  // At Brewster's angle R = rs^2 / 2 exactly; check against the closed-form rs there.
  const float n = 1.5f;
  const float thb = std::atan(n);
  float ct;
  const float R = fresnel_dielectric(std::cos(thb), 1.0f, n, &ct);
  const float tht = std::asin(std::sin(thb) / n);
  const float rs = std::sin(tht - thb) / std::sin(tht + thb);
  EXPECT_NEAR(R, 0.5f * rs * rs, 1e-6f);
}

TEST(Fresnel, RefractionObeysSnellsLaw) {
  const Vec3f n{0, 1, 0};
  const Vec3f d = normalize(Vec3f{1, -1, 0});
  const float cos_i = -dot(d, n);
  float cos_t;
  fresnel_dielectric(cos_i, 1.0f, 1.33f, &cos_t);
  const Vec3f t = refract(d, n, 1.0f / 1.33f, cos_i, cos_t);
  const float sin_i = std::sqrt(1 - cos_i * cos_i);
  const float sin_t = std::sqrt(1 - dot(t, n) * dot(t, n));
  EXPECT_NEAR(sin_i, 1.33f * sin_t, 1e-6f);
  EXPECT_LT(t.y, 0.0f);
}

}  // namespace
}  // namespace tessera

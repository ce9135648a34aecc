// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace tessera::rays {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(RayCheck, AcceptsOrdinaryRays) {
  EXPECT_EQ(check_ray({{0, 0, 0}, {0, 0, 1}}, 0), "");
  EXPECT_EQ(check_ray({{1e30, 0, 0}, {1e-300, 0, 0}, 0.5f, 0.5f}, 0), "");  // tiny d, t_min == t_max
}

TEST(RayCheck, NamesTheRayAndTheField) {
  struct Case {
    WorldRay ray;
    const char* field;
    const char* text;
  };
  const Case cases[] = {
      {{{kNaN, 0, 0}, {0, 0, 1}}, "origin", "ray 7: origin is not finite"},
      {{{0, -2e30, 0}, {0, 0, 1}}, "origin", "ray 7: origin is beyond 1e30"},
      {{{0, 0, 0}, {0, kNaN, 1}}, "direction", "ray 7: direction is not finite"},
      {{{0, 0, 0}, {0, kInf, 1}}, "direction", "ray 7: direction is not finite"},
      {{{0, 0, 0}, {0, 0, 0}}, "direction", "ray 7: direction is zero-length"},
      {{{0, 0, 0}, {0, 0, 1}, -1.0f}, "t_min", "ray 7: t_min must be finite and >= 0"},
      {{{0, 0, 0}, {0, 0, 1}, kNaN}, "t_min", "ray 7: t_min must be finite and >= 0"},
      {{{0, 0, 0}, {0, 0, 1}, 0.0f, kNaN}, "t_max", "ray 7: t_max is NaN"},
      {{{0, 0, 0}, {0, 0, 1}, 2.0f, 1.0f}, "t_min", "ray 7: t_min > t_max"},
  };
  for (const Case& c : cases) {
    std::string field;
    const std::string p = check_ray(c.ray, 7, &field);
    EXPECT_EQ(field, c.field) << c.text;
    EXPECT_EQ(p.rfind(c.text, 0), 0u) << p;
    EXPECT_EQ(check_ray(c.ray, 7), p);  // the field is only said when asked
  }
}

}  // namespace
}  // namespace tessera::rays

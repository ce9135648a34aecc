// SPDX-License-Identifier: Apache-2.0
#include "render/plane.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tessera {
namespace {

TEST(Plane, HitsInFront) {
  EXPECT_DOUBLE_EQ(intersect_plane({0, 5, 0}, {0, -1, 0}, {0, 0, 0}, {0, 1, 0}), 5.0);
  // From below (the back side) it is hit too: planes are two-sided surfaces.
  EXPECT_DOUBLE_EQ(intersect_plane({0, -2, 0}, {0, 1, 0}, {0, 0, 0}, {0, 1, 0}), 2.0);
}

TEST(Plane, BehindTheOriginIsNoHit) {
  EXPECT_TRUE(std::isinf(intersect_plane({0, 5, 0}, {0, 1, 0}, {0, 0, 0}, {0, 1, 0})));
}

TEST(Plane, ParallelRaysNeverHitAndNeverProduceNaN) {
  const double t1 = intersect_plane({0, 5, 0}, {1, 0, 0}, {0, 0, 0}, {0, 1, 0});
  const double t2 = intersect_plane({0, 0, 0}, {1, 0, 0}, {0, 0, 0}, {0, 1, 0});  // in the plane
  EXPECT_TRUE(std::isinf(t1));
  EXPECT_TRUE(std::isinf(t2));
  EXPECT_FALSE(std::isnan(t1));
  EXPECT_FALSE(std::isnan(t2));
}

TEST(Plane, GrazingRaysGiveFinitePositiveT) {
  for (int k = 1; k < 300; k += 7) {
    const Vec3d d = normalize(Vec3d{1, -std::ldexp(1.0, -k), 0});
    const double t = intersect_plane({0, 1e-3, 0}, d, {0, 0, 0}, {0, 1, 0});
    EXPECT_FALSE(std::isnan(t));
    EXPECT_GE(t, 0.0);
  }
}

}  // namespace
}  // namespace tessera

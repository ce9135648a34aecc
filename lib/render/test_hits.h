// SPDX-License-Identifier: Apache-2.0
// Comparisons of hits the renderer's tests share.
#pragma once

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <string>
#include <tuple>

#include "render/hit.h"

namespace tessera::test {

// Every field of two hits, bit for bit (so -0 and +0 differ; padding is not compared).
inline void expect_identical_hit(bool found_a, const Hit& a, bool found_b, const Hit& b, const std::string& what) {
  ASSERT_EQ(found_a, found_b) << what;
  if (!found_a) return;
  auto bits = [](const Vec3f& v) { return std::tuple(std::bit_cast<uint32_t>(v.x), std::bit_cast<uint32_t>(v.y), std::bit_cast<uint32_t>(v.z)); };
  EXPECT_EQ(std::bit_cast<uint32_t>(a.t), std::bit_cast<uint32_t>(b.t)) << what;
  EXPECT_EQ(bits(a.p), bits(b.p)) << what;
  EXPECT_EQ(bits(a.p_err), bits(b.p_err)) << what;
  EXPECT_EQ(bits(a.n), bits(b.n)) << what;
  EXPECT_EQ(a.material, b.material) << what;
  EXPECT_EQ(a.prim, b.prim) << what;
  EXPECT_EQ(std::tuple(std::bit_cast<uint32_t>(a.u), std::bit_cast<uint32_t>(a.v), std::bit_cast<uint32_t>(a.tex_u),
                       std::bit_cast<uint32_t>(a.tex_v)),
            std::tuple(std::bit_cast<uint32_t>(b.u), std::bit_cast<uint32_t>(b.v), std::bit_cast<uint32_t>(b.tex_u),
                       std::bit_cast<uint32_t>(b.tex_v)))
      << what;
  ASSERT_EQ(a.smooth, b.smooth) << what;
  if (a.smooth) {
    EXPECT_EQ(bits(a.ns), bits(b.ns)) << what;
  }
}

}  // namespace tessera::test

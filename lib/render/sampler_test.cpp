#include "render/sampler.h"

#include <gtest/gtest.h>

#include <set>
#include <vector>

namespace tessera {
namespace {

TEST(Sampler, CmjIsAPermutationStratifiedInBothAxes) {
  for (uint32_t n : {1u, 2u, 7u, 16u, 17u, 64u, 100u}) {
    const uint32_t m = uint32_t(std::sqrt(double(n)));
    const uint32_t k = (n + m - 1) / m;
    std::multiset<uint32_t> rows;
    for (uint32_t s = 0; s < n; ++s) {
      float x, y;
      cmj_sample(s, n, 1234, &x, &y);
      ASSERT_GE(x, 0.0f);
      ASSERT_LT(x, 1.0f);
      ASSERT_GE(y, 0.0f);
      ASSERT_LT(y, 1.0f);
      rows.insert(uint32_t(y * float(n)));  // y is stratified into n strata
      (void)k;
    }
    for (uint32_t i = 0; i < n; ++i) EXPECT_EQ(rows.count(i), 1u) << "n=" << n << " stratum " << i;
  }
}

TEST(Sampler, CmjFillsEveryCellOfAnExactGridWhenOneExists) {
  // n = 32 used to get a 5 x 7 grid with 3 empty cells; now 4 x 8, every cell (and every one of
  // the n fine x strata) holding exactly one sample. Primes keep Kensler's partial grid.
  for (uint32_t n : {2u, 8u, 18u, 32u, 128u, 512u, 2048u}) {
    const uint32_t m = cmj_columns(n), k = n / m;
    ASSERT_EQ(m * k, n) << n;
    ASSERT_LE(k, 4 * m) << n;
    std::set<uint32_t> cells, fine_x;
    for (uint32_t s = 0; s < n; ++s) {
      float x, y;
      cmj_sample(s, n, 99, &x, &y);
      cells.insert(uint32_t(x * float(m)) * k + uint32_t(y * float(k)));
      fine_x.insert(uint32_t(x * float(n)));
    }
    EXPECT_EQ(cells.size(), n) << n;
    EXPECT_EQ(fine_x.size(), n) << n;
  }
  EXPECT_EQ(cmj_columns(31), 5u);  // prime: Kensler's 5 x 7
}

TEST(Sampler, PermuteIsABijection) {
  for (uint32_t l : {1u, 3u, 16u, 1000u}) {
    std::set<uint32_t> seen;
    for (uint32_t i = 0; i < l; ++i) seen.insert(cmj_permute(i, l, 0xdeadbeef));
    EXPECT_EQ(seen.size(), l);
    EXPECT_LT(*seen.rbegin(), l);
  }
}

TEST(Sampler, SamplesArePureFunctionsOfTheirKey) {
  const PixelSampler a(SamplerKind::kStratified, 7, 3, 10, 20, 5, 16);
  const PixelSampler b(SamplerKind::kStratified, 7, 3, 10, 20, 5, 16);
  float u1, v1, u2, v2;
  a.get_2d(42, &u1, &v1);
  b.get_2d(42, &u2, &v2);
  EXPECT_EQ(u1, u2);
  EXPECT_EQ(v1, v2);
  // A different pixel, frame, seed or dimension gives a different sample.
  const PixelSampler c(SamplerKind::kStratified, 7, 4, 10, 20, 5, 16);
  c.get_2d(42, &u2, &v2);
  EXPECT_NE(u1, u2);
  a.get_2d(43, &u2, &v2);
  EXPECT_NE(u1, u2);
}

TEST(Sampler, StratifiedBeatsIndependentOnASmoothIntegrand) {
  // Integrate f(x,y) = x*y (exact 1/4) over many pixels; stratified error must be far smaller.
  auto rms_error = [](SamplerKind kind) {
    double se = 0;
    for (int px = 0; px < 200; ++px) {
      double sum = 0;
      for (uint32_t s = 0; s < 64; ++s) {
        const PixelSampler ps(kind, 1, 0, px, 0, s, 64);
        float u, v;
        ps.get_2d(0, &u, &v);
        sum += double(u) * double(v);
      }
      const double e = sum / 64 - 0.25;
      se += e * e;
    }
    return std::sqrt(se / 200);
  };
  EXPECT_LT(rms_error(SamplerKind::kStratified) * 4, rms_error(SamplerKind::kIndependent));
}

}  // namespace
}  // namespace tessera

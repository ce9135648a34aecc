// SPDX-License-Identifier: Apache-2.0
#include "render/sampler.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <algorithm>
#include <bit>
#include <iterator>
#include <random>
#include <set>
#include <string>
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
  const PixelSampler a(SamplerKind::kSobol, 7, 3, 10, 20, 5, 16);
  const PixelSampler b(SamplerKind::kSobol, 7, 3, 10, 20, 5, 16);
  float u1, v1, u2, v2;
  a.get_2d(42, &u1, &v1);
  b.get_2d(42, &u2, &v2);
  EXPECT_EQ(u1, u2);
  EXPECT_EQ(v1, v2);
  // A different pixel, frame, seed or dimension gives a different sample.
  const PixelSampler c(SamplerKind::kSobol, 7, 4, 10, 20, 5, 16);
  c.get_2d(42, &u2, &v2);
  EXPECT_NE(u1, u2);
  a.get_2d(43, &u2, &v2);
  EXPECT_NE(u1, u2);
}

// Whether points are a (0,m,2)-net: every elementary interval of area 2^-m (2^a x 2^(m-a) cells,
// for every a) holds exactly one of the 2^m points.
bool is_02_net(const std::vector<std::pair<float, float>>& pts, int m) {
  for (int a = 0; a <= m; ++a) {
    const uint32_t nx = 1u << a, ny = 1u << (m - a);
    std::vector<int> count(size_t(nx) * ny, 0);
    for (const auto& [x, y] : pts) ++count[size_t(uint32_t(x * float(nx))) * ny + uint32_t(y * float(ny))];
    for (int c : count) {
      if (c != 1) return false;
    }
  }
  return true;
}

TEST(Sampler, OwenSobolEveryPowerOfTwoPrefixOfEachStreamIsA02Net) {
  // The progressive property the adaptive renderer relies on: whatever count a pixel stops at,
  // its first 2^m samples of each stream are as stratified as a net can be.
  for (uint64_t key : {0ull, 1ull, 0xdeadbeefull, 123456789ull}) {
    std::vector<std::pair<float, float>> pts;
    for (uint32_t i = 0; i < 1024; ++i) {
      float u, v;
      owen_sobol_2d(i, key, &u, &v);
      ASSERT_GE(u, 0.0f);
      ASSERT_LT(u, 1.0f);
      ASSERT_GE(v, 0.0f);
      ASSERT_LT(v, 1.0f);
      pts.emplace_back(u, v);
      const uint32_t n = i + 1;
      if ((n & (n - 1)) == 0) {
        EXPECT_TRUE(is_02_net(pts, std::countr_zero(n))) << "key " << key << " prefix " << n;
      }
    }
  }
}

TEST(Sampler, OwenSobolWithoutScramblingIsTheSobolSequence) {
  // Unscrambled reference values: the first Sobol points in index (not Gray-code) order,
  // (0,0), (.5,.5), (.25,.75), (.75,.25), (.125,.625), (.625,.125); and an index shuffle maps
  // [0, 2^m) onto one aligned block.
  const float want[6][2] = {{0, 0}, {.5f, .5f}, {.25f, .75f}, {.75f, .25f}, {.125f, .625f}, {.625f, .125f}};
  for (uint32_t i = 0; i < 6; ++i) {
    uint32_t x, y;
    sobol_2d(i, &x, &y);
    EXPECT_EQ(to_unit_float(x), want[i][0]) << i;
    EXPECT_EQ(to_unit_float(y), want[i][1]) << i;
  }
  for (uint32_t seed : {1u, 77u, 0xabcdef01u}) {
    std::set<uint32_t> blocks, all;
    for (uint32_t i = 0; i < 256; ++i) {
      const uint32_t j = nested_uniform_scramble(i, seed);
      blocks.insert(j >> 8);
      all.insert(j);
    }
    EXPECT_EQ(blocks.size(), 1u) << seed;  // one aligned block of 256 indices
    EXPECT_EQ(all.size(), 256u) << seed;   // a permutation of it
  }
}

// owen_sobol_2d is computed with shortcuts (byte tables, reversals cancelled); it must equal its
// definition: the shuffled index's Sobol point, each coordinate nested-uniform scrambled.
TEST(Sampler, OwenSobolEqualsItsDefinitionBitForBit) {
  for (uint64_t key : {1ull, 42ull, 0x9e3779b97f4a7c15ull, 0xffffffffffffffffull}) {
    const uint64_t h = mix64(key);
    for (uint32_t index = 0; index < 5000; ++index) {
      const uint32_t i = nested_uniform_scramble(index, uint32_t(key)) & 0xffffu;
      uint32_t x, y;
      sobol_2d(i, &x, &y);
      float u, v;
      owen_sobol_2d(index, key, &u, &v);
      ASSERT_EQ(u, to_unit_float(nested_uniform_scramble(x, uint32_t(h)))) << index;
      ASSERT_EQ(v, to_unit_float(nested_uniform_scramble(y, uint32_t(h >> 32)))) << index;
    }
  }
}

// Lane k's inputs, for failure messages.
std::string lane_inputs(const OwenSobolLanes& lanes, int k) {
  return "lane " + std::to_string(k) + " index " + std::to_string(lanes.index[k]) + " seeds " +
         std::to_string(lanes.seed_index[k]) + " " + std::to_string(lanes.seed_x[k]) + " " +
         std::to_string(lanes.seed_y[k]);
}

// owen_sobol_2d_lanes against the scalar owen_sobol_2d, every lane, on every SIMD target this
// machine runs: random indices and seeds, and the edges of both (0, all ones, the top bit, the
// 16-bit boundary the shuffled index is cut at), each lane given different ones so that a lane
// that computed a neighbour's point, or reversed its bits in another order, is caught. The
// outputs start one element past an aligned address: they need no alignment.
TEST(Sampler, OwenSobolLanesEqualTheScalarPointsOnEveryTarget) {
  const uint32_t edges[] = {0u, 1u, 2u, 0xffffu, 0x10000u, 0x7fffffffu, 0x80000000u, 0xfffffffeu, 0xffffffffu};
  std::mt19937 rng(11);
  auto pick = [&] { return rng() % 3 == 0 ? edges[rng() % std::size(edges)] : uint32_t(rng()); };
  OwenSobolLanes lanes;
  alignas(32) float out[2 * kOwenLanes + 1];
  float* const u = out + 1;
  float* const v = u + kOwenLanes;
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    for (int call = 0; call < 20000; ++call) {
      for (int k = 0; k < kOwenLanes; ++k) {
        lanes.index[k] = pick();
        lanes.seed_index[k] = pick();
        lanes.seed_x[k] = pick();
        lanes.seed_y[k] = pick();
      }
      owen_sobol_2d_lanes(lanes, u, v);
      for (int k = 0; k < kOwenLanes; ++k) {
        OwenSeeds seeds(0);
        seeds.index = lanes.seed_index[k];
        seeds.x = lanes.seed_x[k];
        seeds.y = lanes.seed_y[k];
        float want_u, want_v;
        owen_sobol_2d(lanes.index[k], seeds, &want_u, &want_v);
        ASSERT_EQ(std::bit_cast<uint32_t>(u[k]), std::bit_cast<uint32_t>(want_u)) << lane_inputs(lanes, k);
        ASSERT_EQ(std::bit_cast<uint32_t>(v[k]), std::bit_cast<uint32_t>(want_v)) << lane_inputs(lanes, k);
      }
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

// The lanes against owen_sobol_2d's definition (the shuffled index's Sobol point from sobol_2d's
// loop over direction numbers, each coordinate nested-uniform scrambled), for 2^16 consecutive
// indices of a stream: the shuffle maps them onto all 2^16 shuffled indices the point depends on,
// so each target's Pascal-matrix dimension (computed, not looked up as the scalar code does) is
// checked for every one, in every lane.
TEST(Sampler, OwenSobolLanesEqualTheDefinitionForEveryShuffledIndexOnEveryTarget) {
  for (int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(hwy::TargetName(target));
    for (uint64_t key : {7ull, 0xfedcba9876543210ull}) {
      const OwenSeeds seeds(key);
      OwenSobolLanes lanes;
      std::fill_n(lanes.seed_index, kOwenLanes, seeds.index);
      std::fill_n(lanes.seed_x, kOwenLanes, seeds.x);
      std::fill_n(lanes.seed_y, kOwenLanes, seeds.y);
      std::set<uint32_t> shuffled;
      for (uint32_t first = 0; first < 0x10000u; first += kOwenLanes) {
        for (int k = 0; k < kOwenLanes; ++k) lanes.index[k] = first + uint32_t(k);
        float u[kOwenLanes], v[kOwenLanes];
        owen_sobol_2d_lanes(lanes, u, v);
        for (int k = 0; k < kOwenLanes; ++k) {
          const uint32_t i = nested_uniform_scramble(lanes.index[k], seeds.index) & 0xffffu;
          shuffled.insert(i);
          uint32_t x, y;
          sobol_2d(i, &x, &y);
          const float want_u = to_unit_float(nested_uniform_scramble(x, seeds.x));
          const float want_v = to_unit_float(nested_uniform_scramble(y, seeds.y));
          ASSERT_EQ(std::bit_cast<uint32_t>(u[k]), std::bit_cast<uint32_t>(want_u)) << lane_inputs(lanes, k);
          ASSERT_EQ(std::bit_cast<uint32_t>(v[k]), std::bit_cast<uint32_t>(want_v)) << lane_inputs(lanes, k);
        }
      }
      EXPECT_EQ(shuffled.size(), 0x10000u);
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

TEST(Sampler, CameraSamplerGivesEachSamplersPixelOffsetsBitForBit) {
  for (SamplerKind kind : {SamplerKind::kSobol, SamplerKind::kCmj, SamplerKind::kIndependent, SamplerKind::kCenter}) {
    for (int px : {0, 17, 1919}) {
      const uint64_t key = PixelSampler::pixel_key(5, 3, px, 7);
      const CameraSampler camera(kind, key, 64);
      for (uint32_t s = 0; s < 64; ++s) {
        float u0, v0, u1, v1;
        PixelSampler(kind, 5, 3, px, 7, s, 64).pixel_offset(&u0, &v0);
        camera.pixel_offset(s, &u1, &v1);
        ASSERT_EQ(u0, u1) << int(kind) << " " << px << " " << s;
        ASSERT_EQ(v0, v1) << int(kind) << " " << px << " " << s;
      }
    }
  }
}

TEST(Sampler, StreamsAreIndependentPatternsAndSamplesDoNotDependOnSpp) {
  // Even samples form stream 0, odd ones stream 1, each its own scrambled net; a progressive
  // sampler gives sample s the same value whatever the final spp (an adaptive pixel that stops at
  // n samples took the same samples as a uniform n-spp render).
  std::vector<std::pair<float, float>> s0, s1;
  for (uint32_t s = 0; s < 64; ++s) {
    const PixelSampler a(SamplerKind::kSobol, 5, 0, 3, 4, s, 64), b(SamplerKind::kSobol, 5, 0, 3, 4, s, 1000);
    float u, v, u2, v2;
    a.get_2d(0, &u, &v);
    b.get_2d(0, &u2, &v2);
    EXPECT_EQ(u, u2);
    EXPECT_EQ(v, v2);
    (s % 2 == 0 ? s0 : s1).emplace_back(u, v);
  }
  EXPECT_TRUE(is_02_net(s0, 5));
  EXPECT_TRUE(is_02_net(s1, 5));
  EXPECT_NE(s0, s1);
  EXPECT_EQ(stream_count(0, 7), 4u);
  EXPECT_EQ(stream_count(1, 7), 3u);
}

TEST(Sampler, CmjStreamsAreEachStratifiedOverTheirOwnCount) {
  for (uint32_t spp : {16u, 17u}) {
    std::multiset<uint32_t> rows[2];
    for (uint32_t s = 0; s < spp; ++s) {
      const PixelSampler ps(SamplerKind::kCmj, 1, 0, 7, 7, s, spp);
      float u, v;
      ps.get_2d(0, &u, &v);
      rows[sample_stream(s)].insert(uint32_t(v * float(stream_count(sample_stream(s), spp))));
    }
    for (uint32_t k = 0; k < 2; ++k) {
      for (uint32_t i = 0; i < stream_count(k, spp); ++i) EXPECT_EQ(rows[k].count(i), 1u) << spp << " " << k << " " << i;
    }
  }
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
  EXPECT_LT(rms_error(SamplerKind::kSobol) * 4, rms_error(SamplerKind::kIndependent));
  EXPECT_LT(rms_error(SamplerKind::kCmj) * 4, rms_error(SamplerKind::kIndependent));
}

}  // namespace
}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "render/sampler.h"

namespace tessera {

namespace {

// Called seven times per 2D point: inline, and the byte order reversed by one bswap.
[[gnu::always_inline]] inline uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  return __builtin_bswap32(x);
}

// A bijection of 32-bit words in which output bit b depends only on input bits <= b (products
// and sums carry upwards only): applied to bit-reversed words, that is a nested uniform scramble.
// Constants from Vegdahl, "Building a Better LK Hash" (2021), which fixes the weak low-order
// mixing of Burley's original.
uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x ^= x * 0x3d20adeau;
  x += seed;
  x *= (seed >> 16) | 1u;
  x ^= x * 0x05526c56u;
  x ^= x * 0x53a22864u;
  return x;
}

// Direction numbers of Sobol's second dimension (primitive polynomial x + 1): the Pascal matrix
// mod 2, column k = bit 31-k and every bit below it that C(k, j) is odd for.
struct SobolDim1 {
  uint32_t v[32];
  constexpr SobolDim1() : v() {
    v[0] = 1u << 31;
    for (int k = 1; k < 32; ++k) v[k] = v[k - 1] ^ (v[k - 1] >> 1);
  }
};
constexpr SobolDim1 kSobolDim1;

// The same dimension for a 16-bit index, one table per byte: y = lo[i & 255] ^ hi[i >> 8]
// (the matrix is linear over GF(2), so the bytes' contributions XOR).
struct SobolDim1Bytes {
  uint32_t lo[256], hi[256];
  constexpr SobolDim1Bytes() : lo(), hi() {
    for (uint32_t b = 0; b < 256; ++b) {
      for (int k = 0; k < 8; ++k) {
        if (b & (1u << k)) {
          lo[b] ^= kSobolDim1.v[k];
          hi[b] ^= kSobolDim1.v[k + 8];
        }
      }
    }
  }
};
constexpr SobolDim1Bytes kSobolDim1Bytes;

// The same tables bit-reversed (reversal distributes over XOR), for the scramble below, which
// works on reversed words.
struct SobolDim1BytesReversed {
  uint32_t lo[256], hi[256];
  constexpr SobolDim1BytesReversed() : lo(), hi() {
    auto rev = [](uint32_t x) {
      uint32_t r = 0;
      for (int b = 0; b < 32; ++b) r |= ((x >> b) & 1u) << (31 - b);
      return r;
    };
    for (int b = 0; b < 256; ++b) {
      lo[b] = rev(kSobolDim1Bytes.lo[b]);
      hi[b] = rev(kSobolDim1Bytes.hi[b]);
    }
  }
};
constexpr SobolDim1BytesReversed kSobolDim1BytesReversed;

}  // namespace

uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

void sobol_2d(uint32_t index, uint32_t* x, uint32_t* y) {
  *x = reverse_bits(index);  // van der Corput: the first dimension's matrix is the identity
  uint32_t v = 0;
  for (int k = 0; index != 0; ++k, index >>= 1) {
    if (index & 1u) v ^= kSobolDim1.v[k];
  }
  *y = v;
}

void owen_sobol_2d(uint32_t index, uint64_t seed, float* u, float* v) { owen_sobol_2d(index, OwenSeeds(seed), u, v); }

void owen_sobol_2d(uint32_t index, const OwenSeeds& seeds, float* u, float* v) {
  // Only the low 16 bits of the shuffled index are used: the bits above them are the same for
  // every index of a stream below 2^16 (the shuffle flips a bit by the bits above it), and by
  // linearity they only XOR a constant into the point, a digital shift, which the Owen scramble
  // that follows absorbs (a nested uniform scramble of a shifted net is a nested uniform scramble
  // of the net). 16 bits cover 2^16 samples per stream, twice what SceneLimits::kMaxSpp allows
  // a stream (its half of 65536); two table
  // lookups replace a loop over 32 bits.
  const uint32_t i = nested_uniform_scramble(index, seeds.index) & 0xffffu;
  // x = reverse(i) and y = the Pascal-matrix dimension, each scrambled by
  // nested_uniform_scramble(w, s) = reverse(LK(reverse(w), s)): reverse(x) is i itself, and
  // reverse(y) comes from the reversed tables, so two of the four reversals fall away.
  const uint32_t y_reversed = kSobolDim1BytesReversed.lo[i & 0xffu] ^ kSobolDim1BytesReversed.hi[i >> 8];
  *u = to_unit_float(reverse_bits(laine_karras_permutation(i, seeds.x)));
  *v = to_unit_float(reverse_bits(laine_karras_permutation(y_reversed, seeds.y)));
}

uint32_t cmj_permute(uint32_t i, uint32_t l, uint32_t p) {
  uint32_t w = l - 1;
  w |= w >> 1;
  w |= w >> 2;
  w |= w >> 4;
  w |= w >> 8;
  w |= w >> 16;
  do {
    i ^= p;
    i *= 0xe170893d;
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i *= 0x0929eb3f;
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i *= 1 | p >> 27;
    i *= 0x6935fa69;
    i ^= (i & w) >> 11;
    i *= 0x74dcb303;
    i ^= (i & w) >> 2;
    i *= 0x9e501cc3;
    i ^= (i & w) >> 2;
    i *= 0xc860a3df;
    i &= w;
    i ^= i >> 5;
  } while (i >= l);
  return (i + p) % l;
}

float cmj_randfloat(uint32_t i, uint32_t p) {
  i ^= p;
  i ^= i >> 17;
  i ^= i >> 10;
  i *= 0xb36534e5;
  i ^= i >> 12;
  i ^= i >> 21;
  i *= 0x93fc4795;
  i ^= 0xdf6e307f;
  i ^= i >> 17;
  i *= 1 | p >> 18;
  return to_unit_float(i);
}

uint32_t cmj_columns(uint32_t n) {
  // Kensler's aspect-1 choice, m = floor(sqrt(n)) columns of k = ceil(n / m) rows, leaves the last
  // row partly empty when m does not divide n (n = 32: 5 x 7 = 35 cells). The unused cells are
  // x sub-strata no sample covers, an O(1/n) error that made 32 spp worse than 12 on smooth
  // pixels (tests/stability convergence). Prefer an exact factorization n = m k with aspect at
  // most 4 (every power of two has one); fall back to Kensler's grid otherwise (e.g. primes).
  const uint32_t root = uint32_t(std::sqrt(double(n)));
  for (uint32_t m = root; m >= 1 && 4ull * m * m >= n; --m) {
    if (n % m == 0) return m;
  }
  return root;
}

void cmj_sample(uint32_t s, uint32_t n, uint32_t p, float* x, float* y) {
  const uint32_t m = cmj_columns(n);
  const uint32_t k = (n + m - 1) / m;
  s = cmj_permute(s, n, p * 0x51633e2d);
  const uint32_t sx = cmj_permute(s % m, m, p * 0x68bc21eb);
  const uint32_t sy = cmj_permute(s / m, k, p * 0x02e5be93);
  const float jx = cmj_randfloat(s, p * 0x967a889b);
  const float jy = cmj_randfloat(s, p * 0x368cc8b7);
  float fx = (float(sx) + (float(sy) + jx) / float(k)) / float(m);
  float fy = (float(s) + jy) / float(n);
  // Guard [0,1): float rounding of the sums can land exactly on 1.
  *x = fx < 1.0f ? fx : 0x1.fffffep-1f;
  *y = fy < 1.0f ? fy : 0x1.fffffep-1f;
}

}  // namespace tessera

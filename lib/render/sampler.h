// Counter-based sample generation: every number is a pure function of
// (seed, frame, pixel, sample index, dimension), so a pixel's value does not depend on tile
// size, tile order, thread count or how many times a tile is rendered.
#pragma once

#include <cmath>
#include <cstdint>

#include "scene/scene.h"

namespace tessera {

// 64-bit finalizer of MurmurHash3 / SplitMix64: full avalanche, cheap.
constexpr uint64_t mix64(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}

constexpr uint64_t hash_combine(uint64_t h, uint64_t v) { return mix64(h ^ (v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2))); }

// Uniform float in [0, 1) from the top 24 bits: exactly representable, never 1.0.
constexpr float to_unit_float(uint32_t bits) { return float(bits >> 8) * 0x1p-24f; }

// Kensler, "Correlated Multi-Jittered Sampling" (Pixar Tech Memo 13-01, 2013): sample s of
// n stratified 2D samples, for any n, under the random pattern p. permute() is his
// cycle-walking hash permutation of [0, l).
uint32_t cmj_permute(uint32_t i, uint32_t l, uint32_t p);
float cmj_randfloat(uint32_t i, uint32_t p);
void cmj_sample(uint32_t s, uint32_t n, uint32_t p, float* x, float* y);
// Columns of the m x k grid cmj_sample stratifies n samples into (m k = n whenever n has a
// factorization of aspect <= 4).
uint32_t cmj_columns(uint32_t n);

// Sample source for one pixel sample. A "dimension key" names which 2D decision is being made
// (pixel position, area-light sample for light L at path node K, ...).
class PixelSampler {
 public:
  PixelSampler(SamplerKind kind, uint64_t seed, int frame, int px, int py, uint32_t sample, uint32_t spp)
      : kind_(kind), sample_(sample), spp_(spp) {
    pixel_key_ = hash_combine(hash_combine(hash_combine(mix64(seed), uint64_t(uint32_t(frame))),
                                           uint64_t(uint32_t(px))),
                              uint64_t(uint32_t(py)));
  }

  // A 2D point in [0,1)^2 for the decision named by `dim`.
  void get_2d(uint64_t dim, float* u, float* v) const {
    const uint64_t key = hash_combine(pixel_key_, dim);
    if (kind_ == SamplerKind::kIndependent) {
      const uint64_t bits = hash_combine(key, sample_);
      *u = to_unit_float(uint32_t(bits));
      *v = to_unit_float(uint32_t(bits >> 32));
    } else {
      // The pattern is shared by all samples of the pixel (that is what stratifies them),
      // different per pixel and per dimension (decorrelating dimensions, "padding").
      cmj_sample(sample_, spp_, uint32_t(key), u, v);
    }
  }

  // The pixel-area position, center-only for SamplerKind::kCenter.
  void pixel_offset(float* u, float* v) const {
    if (kind_ == SamplerKind::kCenter) {
      *u = 0.5f;
      *v = 0.5f;
      return;
    }
    get_2d(0, u, v);
  }

 private:
  SamplerKind kind_;
  uint32_t sample_;
  uint32_t spp_;
  uint64_t pixel_key_;
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Counter-based sample generation: every number is a pure function of
// (seed, frame, pixel, sample index, dimension), so a pixel's value does not depend on tile
// size, tile order, thread count or how many times a tile is rendered.
//
// Every sampler splits a pixel's samples into two interleaved, independent streams (even sample
// indices form stream 0, odd ones stream 1), each stratified on its own. The difference of the
// two streams' means is what makes the error estimate honest for stratified samples (see
// docs/renderer.md, "Error estimate"): the samples within one stratified set are negatively
// correlated, so their sample variance overstates the error, while two independently scrambled
// sets are independent by construction.
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

// The stream (0 or 1) a pixel sample belongs to, its index within that stream, and how many of
// a pixel's first n samples each stream holds.
constexpr uint32_t sample_stream(uint32_t sample) { return sample & 1u; }
constexpr uint32_t stream_index(uint32_t sample) { return sample >> 1; }
constexpr uint32_t stream_count(uint32_t stream, uint32_t n) { return stream == 0 ? (n + 1) / 2 : n / 2; }

// Owen-scrambled Sobol (0,2)-sequence, Burley, "Practical Hash-based Owen Scrambling" (JCGT 9(4),
// 2020), with the Laine-Karras-style hash improved by N. Vegdahl (2021).
//  - nested_uniform_scramble: a base-2 Owen scramble of a 32-bit fixed-point number. Bit b is
//    flipped by a hash of the bits above it, so every elementary interval maps onto one of the
//    same size: a (0,m,2)-net stays a (0,m,2)-net.
//  - sobol_2d: the first two Sobol dimensions (van der Corput and the Pascal-matrix dimension);
//    any 2^m consecutive indices starting at a multiple of 2^m form a (0,m,2)-net.
//  - owen_sobol_2d: index shuffled by nested_uniform_scramble (it maps the indices [0, 2^m) onto
//    one aligned block of 2^m indices, so every power-of-two prefix stays a net), then both
//    coordinates scrambled with independent seeds.
uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed);
void sobol_2d(uint32_t index, uint32_t* x, uint32_t* y);
void owen_sobol_2d(uint32_t index, uint64_t seed, float* u, float* v);
// The three 32-bit seeds owen_sobol_2d derives from its 64-bit one (index shuffle, x, y), for
// callers that draw many points under one seed.
struct OwenSeeds {
  uint32_t index, x, y;
  constexpr explicit OwenSeeds(uint64_t seed)
      : index(uint32_t(seed)), x(uint32_t(mix64(seed))), y(uint32_t(mix64(seed) >> 32)) {}
};
void owen_sobol_2d(uint32_t index, const OwenSeeds& seeds, float* u, float* v);

// owen_sobol_2d for a packet's lanes at once (structure of arrays, Google Highway at the
// machine's width, picked at run time; render/sampler_simd.cpp): lane i is
// owen_sobol_2d(index[i], {seed_index[i], seed_x[i], seed_y[i]}, &u[i], &v[i]) bit for bit, on
// every target (only exact integer operations, one exact int-to-float conversion and a scaling by
// a power of two; sampler_test.cpp checks every target this machine runs). Every lane is computed:
// a lane the caller leaves unused may hold anything (nothing traps) and its outputs are garbage.
//
// Why: one lane at a time, the camera sample was about a seventh of the instructions of a
// primary-ray-bound frame. On AVX2 a call costs about 150 instructions for 8 lanes, where 8 calls
// of owen_sobol_2d cost about 1150 (cachegrind, dispatch included). The callers pack the samples of several pixels (each lane its own
// stream's seeds) into one packet. Only SamplerKind::kSobol has this path; the other kinds go
// through PixelSampler one sample at a time. The inputs are one struct rather than four arrays
// because the run-time dispatch calls into Highway first, and every pointer argument is one more
// register to save around that call.
inline constexpr int kOwenLanes = 8;  // RenderScene::kPacket
struct OwenSobolLanes {
  alignas(32) uint32_t index[kOwenLanes];  // the sample's index within its stream
  // The lane's stream's OwenSeeds, field by field.
  alignas(32) uint32_t seed_index[kOwenLanes];
  alignas(32) uint32_t seed_x[kOwenLanes];
  alignas(32) uint32_t seed_y[kOwenLanes];
};
// u and v need no alignment.
void owen_sobol_2d_lanes(const OwenSobolLanes& lanes, float u[kOwenLanes], float v[kOwenLanes]);

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
  // `spp` is used by the CMJ sampler only (its pattern depends on the sample count); the others
  // are progressive: sample s is the same whatever the pixel's final sample count.
  PixelSampler() = default;
  PixelSampler(SamplerKind kind, uint64_t seed, int frame, int px, int py, uint32_t sample, uint32_t spp)
      : PixelSampler(kind, pixel_key(seed, frame, px, py), sample, spp) {}
  // The same from the pixel's key, computed once for all of a pixel's samples.
  PixelSampler(SamplerKind kind, uint64_t pixel_key, uint32_t sample, uint32_t spp)
      : kind_(kind), sample_(sample), spp_(spp), pixel_key_(pixel_key) {}
  // One key per (pixel, dimension, stream): independent patterns per stream, and different
  // ones per dimension (decorrelating dimensions, "padding").
  static constexpr uint64_t dimension_key(uint64_t pixel_key, uint64_t dim, uint32_t stream) {
    return hash_combine(hash_combine(pixel_key, dim), stream);
  }
  static constexpr uint64_t pixel_key(uint64_t seed, int frame, int px, int py) {
    return hash_combine(hash_combine(hash_combine(mix64(seed), uint64_t(uint32_t(frame))), uint64_t(uint32_t(px))),
                        uint64_t(uint32_t(py)));
  }

  // A 2D point in [0,1)^2 for the decision named by `dim`.
  void get_2d(uint64_t dim, float* u, float* v) const {
    const uint32_t stream = sample_stream(sample_);
    const uint64_t key = dimension_key(pixel_key_, dim, stream);
    switch (kind_) {
      case SamplerKind::kSobol:
      case SamplerKind::kLattice:  // its edge pixels' samples are the default sampler's
        owen_sobol_2d(stream_index(sample_), key, u, v);
        return;
      case SamplerKind::kCmj:
        cmj_sample(stream_index(sample_), stream_count(stream, spp_), uint32_t(key), u, v);
        return;
      case SamplerKind::kIndependent:
      case SamplerKind::kCenter: {
        const uint64_t bits = hash_combine(key, sample_);
        *u = to_unit_float(uint32_t(bits));
        *v = to_unit_float(uint32_t(bits >> 32));
        return;
      }
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
  SamplerKind kind_ = SamplerKind::kSobol;
  uint32_t sample_ = 0;
  uint32_t spp_ = 0;
  uint64_t pixel_key_ = 0;
};

// The pixel-area positions of one pixel's samples: PixelSampler::pixel_offset, bit for bit, with
// the Sobol scramble's seeds derived once per pixel and stream instead of once per sample (five
// 64-bit hashes a camera ray; the sampler was a tenth of a primary-ray-bound frame).
class CameraSampler {
 public:
  CameraSampler(SamplerKind kind, uint64_t pixel_key, uint32_t spp)
      : kind_(kind), spp_(spp), pixel_key_(pixel_key),
        seeds_{OwenSeeds(PixelSampler::dimension_key(pixel_key, 0, 0)),
               OwenSeeds(PixelSampler::dimension_key(pixel_key, 0, 1))} {}
  void pixel_offset(uint32_t sample, float* u, float* v) const {
    if (kind_ == SamplerKind::kSobol) {
      owen_sobol_2d(stream_index(sample), seeds_[sample_stream(sample)], u, v);
      return;
    }
    PixelSampler(kind_, pixel_key_, sample, spp_).pixel_offset(u, v);
  }
  // For kSobol: the Owen scramble's seeds of the stream `sample` belongs to (owen_sobol_2d_lanes).
  const OwenSeeds& seeds(uint32_t sample) const { return seeds_[sample_stream(sample)]; }

 private:
  SamplerKind kind_;
  uint32_t spp_;
  uint64_t pixel_key_;
  OwenSeeds seeds_[2];
};

}  // namespace tessera

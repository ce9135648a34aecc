// SPDX-License-Identifier: Apache-2.0
// Dithering choices and the ordered-dither threshold maps. Floyd-Steinberg error diffusion
// needs the palette, so it lives with the palette mapping (palette_quantizer.h).
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace tessera::color {

enum class DitherMethod {
  kNone,            // round to nearest
  kBayer,           // ordered, 8x8 Bayer matrix
  kBlueNoise,       // ordered, 64x64 void-and-cluster blue-noise tile
  kFloydSteinberg,  // error diffusion (palette output only), in linear light, serpentine
};

std::string_view dither_name(DitherMethod d);
std::optional<DitherMethod> parse_dither(std::string_view name);

// Thresholds in (0, 1), uniformly distributed over a tile: quantize v (in level units) as
// floor(v + threshold). With kNone the threshold is 0.5, i.e. round to nearest.
float ordered_threshold(DitherMethod d, int x, int y);

// Rank (0..63) of the 8x8 Bayer matrix at (x mod 8, y mod 8).
int bayer_rank(int x, int y);

inline constexpr int kBlueNoiseSize = 64;

// The 64x64 void-and-cluster tile (Ulichney 1993, Gaussian sigma 1.5, toroidal), generated
// once, deterministically, from a fixed-seed initial pattern: a rank 0..4095 per texel,
// row-major. Generated in code rather than shipped as data so its provenance is this file.
const std::vector<uint16_t>& blue_noise_ranks();

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// bfloat16: the top 16 bits of an IEEE-754 float32 (sign, 8-bit exponent, 7 stored mantissa
// bits), float32's range at 8 significant bits. The precision a tile's per-pixel variance is
// kept at: the renderer rounds it here (so an in-process render and a farm render report the
// same error, bit for bit) and the wire carries it in 2 bytes (farm/tile_codec.h). The estimate
// itself is uncertain by tens of percent at the sample counts renders use; 2^-8 is far below it.
// (Hand-written, a few lines: no Debian library offers a bfloat16 conversion on its own.)
#pragma once

#include <bit>
#include <cstdint>

namespace tessera {

// Rounded to nearest even. A finite value that would round up to infinity is truncated instead
// (to the largest finite bfloat16): a finite variance never turns infinite. NaN stays NaN.
inline uint16_t to_bfloat16(float f) {
  const uint32_t u = std::bit_cast<uint32_t>(f);
  if ((u & 0x7f800000u) == 0x7f800000u) return uint16_t((u >> 16) | ((u & 0xffffu) ? 0x40u : 0u));
  const uint32_t rounded = (u + 0x7fffu + ((u >> 16) & 1u)) >> 16;
  return (rounded & 0x7f80u) == 0x7f80u ? uint16_t(u >> 16) : uint16_t(rounded);
}

inline float from_bfloat16(uint16_t h) { return std::bit_cast<float>(uint32_t(h) << 16); }

// `f` at bfloat16 precision, as a float: to_bfloat16 of the result is exact.
inline float round_to_bfloat16(float f) { return from_bfloat16(to_bfloat16(f)); }

}  // namespace tessera

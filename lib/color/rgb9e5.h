// SPDX-License-Identifier: Apache-2.0
// RGB9E5: three 9-bit mantissas sharing one 5-bit exponent in 32 bits, exactly as
// EXT_texture_shared_exponent specifies it (GL_RGB9_E5, also VK_FORMAT_E5B9G9R9_UFLOAT_PACK32
// and DXGI_FORMAT_R9G9B9E5_SHAREDEXP: red in bits 0-8, green 9-17, blue 18-26, exponent 27-31).
#pragma once

#include <cstdint>

#include "color/rgb.h"

namespace tessera::color {

inline constexpr int kRgb9e5MantissaBits = 9;   // N
inline constexpr int kRgb9e5ExponentBias = 15;  // B
inline constexpr int kRgb9e5MaxExponent = 31;   // Emax
// sharedexp_max = (2^N - 1) / 2^N * 2^(Emax - B) = 511/512 * 65536.
inline constexpr float kRgb9e5Max = 65408.0f;

// Per the extension: each channel is clamped to [0, 65408] (NaN and negatives -> 0, our
// documented choice for NaN, which the extension leaves undefined), the shared exponent is
// max(-B-1, floor(log2(max))) + 1 + B, and is incremented when rounding the largest channel
// to N bits carries out to 2^N.
uint32_t encode_rgb9e5(const Rgb& c);

// mantissa * 2^(exponent - B - N) for each channel.
Rgb decode_rgb9e5(uint32_t packed);

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// The sRGB transfer function (IEC 61966-2-1) with its exact constants: the linear segment
// below 0.0031308 (slope 12.92) and 1.055 * x^(1/2.4) - 0.055 above. Evaluated in double so
// that 8-bit rounding decisions do not depend on float pow accuracy.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

#include "color/rgb.h"
#include "image/image.h"

namespace tessera::color {

inline constexpr double kSrgbLinearBreak = 0.0031308;  // linear-side threshold
inline constexpr double kSrgbEncodedBreak = 0.04045;   // encoded-side threshold
inline constexpr double kSrgbSlope = 12.92;
inline constexpr double kSrgbScale = 1.055;
inline constexpr double kSrgbOffset = 0.055;
inline constexpr double kSrgbGamma = 2.4;

// Linear [0, 1] -> encoded [0, 1]. Out-of-range input is clamped; NaN gives 0.
inline double srgb_encode(double linear) {
  if (!(linear > 0.0)) return 0.0;
  if (linear >= 1.0) return 1.0;
  if (linear <= kSrgbLinearBreak) return kSrgbSlope * linear;
  return kSrgbScale * std::pow(linear, 1.0 / kSrgbGamma) - kSrgbOffset;
}

// Encoded [0, 1] -> linear [0, 1]. Out-of-range input is clamped; NaN gives 0.
inline double srgb_decode(double encoded) {
  if (!(encoded > 0.0)) return 0.0;
  if (encoded >= 1.0) return 1.0;
  if (encoded <= kSrgbEncodedBreak) return encoded / kSrgbSlope;
  return std::pow((encoded + kSrgbOffset) / kSrgbScale, kSrgbGamma);
}

// Linear -> nearest 8-bit code value (round half up on the 0..255 scale).
inline uint8_t linear_to_srgb8(double linear) {
  return uint8_t(std::floor(srgb_encode(linear) * 255.0 + 0.5));
}

inline Srgb8 linear_to_srgb8(const Rgb& c) {
  return {linear_to_srgb8(c.r), linear_to_srgb8(c.g), linear_to_srgb8(c.b)};
}

// The 256 linear values of the 8-bit code values (exact decode, rounded once to float).
inline const std::array<float, 256>& srgb8_to_linear_table() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[size_t(i)] = float(srgb_decode(i / 255.0));
    return t;
  }();
  return table;
}

inline Rgb srgb8_to_linear(const Srgb8& c) {
  const auto& t = srgb8_to_linear_table();
  return {t[c.r], t[c.g], t[c.b]};
}

// Linear [0, 1] image -> sRGB-encoded [0, 1] floats (the unquantized display image).
inline ImageRGB srgb_encode_image(const ImageRGB& linear) {
  ImageRGB out(linear.width, linear.height);
  for (size_t i = 0; i < linear.rgb.size(); ++i) out.rgb[i] = float(srgb_encode(linear.rgb[i]));
  return out;
}

}  // namespace tessera::color

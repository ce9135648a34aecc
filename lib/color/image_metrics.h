// SPDX-License-Identifier: Apache-2.0
// How far an encoded image is from its reference.
//
// LDR error: both images are sRGB-encoded values in [0, 1], measured on the 0..255 code-value
// scale. The reference is the *unquantized* tone-mapped image (not rounded to 8 bits), so an
// exact 8-bit PNG shows the rounding it does: about 59 dB, max 0.5.
// HDR error: linear light, relative to the pixel's largest reference channel (the quantity
// shared-exponent formats bound); below kRelativeErrorFloor the denominator is that floor, so
// near-black pixels are judged by absolute error rather than dividing by almost nothing.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "image/image.h"

namespace tessera::color {

inline constexpr double kRelativeErrorFloor = 0x1p-14;  // half's smallest normal, 6.1e-5

struct LdrError {
  double psnr_db = std::numeric_limits<double>::infinity();  // 10 log10(255^2 / MSE)
  double max_abs = 0.0;                                      // in 8-bit code values
  double rmse = 0.0;                                         // in 8-bit code values
};

struct HdrError {
  double max_rel = 0.0;
  double mean_rel = 0.0;  // over the measured pixels
};

double psnr_from_mse(double mse_8bit);

// `include`, when given, has one byte per pixel; pixels with 0 are left out of the measure.
LdrError ldr_error(const ImageRGB& reference_srgb, const ImageRGB& decoded_srgb,
                   const std::vector<uint8_t>* include = nullptr);

HdrError hdr_relative_error(const ImageRGB& reference_linear, const ImageRGB& decoded_linear,
                            const std::vector<uint8_t>* include = nullptr);

// Banding measure: RMS over pixels and channels of the difference (decoded - reference)
// box-filtered with a (2 radius + 1)^2 window, in linear light. A dither trades visible bands
// (large low-frequency error) for fine noise (which the filter averages away).
double low_frequency_error(const ImageRGB& reference_linear, const ImageRGB& decoded_linear,
                           int radius);

}  // namespace tessera::color

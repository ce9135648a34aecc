// SPDX-License-Identifier: Apache-2.0
// The documented, deterministic handling of values a renderer should never produce but
// sometimes does (NaN from 0/0, Inf from a division by a zero pdf, negatives from filters with
// negative lobes). Every encoder goes through these, so no NaN ever reaches an integer format.
//
//   input        unsigned formats (8-bit, 565, palette, RGBE, RGB9E5)   signed (EXR)
//   NaN          0                                                      0
//   +Inf         largest finite float, then the format's clamp          largest finite value
//   -Inf         0                                                      -largest finite value
//   negative     0 (clipped in linear light, before tone mapping)       kept
#pragma once

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <vector>

#include "image/image.h"

namespace tessera::color {

inline float sanitize_unsigned(float v) {
  if (std::isnan(v) || v <= 0.0f) return 0.0f;  // also -Inf and -0
  return v > FLT_MAX ? FLT_MAX : v;
}

inline float sanitize_signed(float v) {
  if (std::isnan(v)) return 0.0f;
  if (v > FLT_MAX) return FLT_MAX;
  if (v < -FLT_MAX) return -FLT_MAX;
  return v;
}

// How many channel values of an input needed the policy above; shown in the report so a
// user learns that the frame had NaNs instead of finding black pixels later.
struct InputStats {
  uint64_t nan = 0;
  uint64_t pos_inf = 0;
  uint64_t neg_inf = 0;
  uint64_t negative = 0;  // finite negative values

  uint64_t total() const { return nan + pos_inf + neg_inf + negative; }
};

inline InputStats count_special_values(const ImageRGB& image) {
  InputStats s;
  for (float v : image.rgb) {
    if (std::isnan(v)) {
      ++s.nan;
    } else if (std::isinf(v)) {
      ++(v > 0 ? s.pos_inf : s.neg_inf);
    } else if (v < 0.0f) {
      ++s.negative;
    }
  }
  return s;
}

// 1 for each pixel whose three input values are finite. Error metrics skip the others: a
// NaN or Inf has no true value to measure against (they are counted in InputStats instead).
inline std::vector<uint8_t> finite_pixel_mask(const ImageRGB& image) {
  std::vector<uint8_t> mask(image.pixel_count(), 1);
  for (size_t p = 0; p < mask.size(); ++p) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(image.rgb[3 * p + size_t(c)])) mask[p] = 0;
    }
  }
  return mask;
}

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// The neighbouring floats of v, up and down: std::nextafter(v, +/-inf) for every input, inline.
// Why not std::nextafter: it is an out-of-line libm call, and ray spawning makes three per
// secondary and shadow ray (render/ray.h): 2% of a Whitted render's time (measured with perf).
// After pbrt-v4's NextFloatUp/NextFloatDown.
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

namespace tessera {

inline float next_float_up(float v) {
  if (std::isinf(v) && v > 0.0f) return v;
  if (v == 0.0f) return std::bit_cast<float>(uint32_t(1));  // from +0 and -0: the smallest denormal
  uint32_t u = std::bit_cast<uint32_t>(v);
  u = v > 0.0f ? u + 1 : u - 1;  // NaN: stays a NaN (its payload moves, as libm's may not)
  return std::bit_cast<float>(u);
}

inline float next_float_down(float v) {
  if (std::isinf(v) && v < 0.0f) return v;
  if (v == 0.0f) return -std::bit_cast<float>(uint32_t(1));
  uint32_t u = std::bit_cast<uint32_t>(v);
  u = v > 0.0f ? u - 1 : u + 1;
  return std::bit_cast<float>(u);
}

}  // namespace tessera

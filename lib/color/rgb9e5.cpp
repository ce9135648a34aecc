// SPDX-License-Identifier: Apache-2.0
#include "color/rgb9e5.h"

#include <algorithm>
#include <cmath>

#include "color/shared_exponent_clamp.h"

namespace tessera::color {

namespace {

// floor(log2(x)) for x > 0, exactly (no rounding of a floating-point log2).
int floor_log2(double x) {
  int e = 0;
  std::frexp(x, &e);  // x = m * 2^e, m in [0.5, 1)
  return e - 1;
}

}  // namespace

uint32_t encode_rgb9e5(const Rgb& c) {
  constexpr int N = kRgb9e5MantissaBits, B = kRgb9e5ExponentBias;
  const double rc = clamp_shared_exponent_channel(c.r, kRgb9e5Max),
               gc = clamp_shared_exponent_channel(c.g, kRgb9e5Max),
               bc = clamp_shared_exponent_channel(c.b, kRgb9e5Max);
  const double max_c = std::max({rc, gc, bc});
  // log2(0) = -inf, so max(-B-1, ...) picks -B-1 and the exponent is 0 for black.
  const int floor_l2 = max_c > 0.0 ? std::max(-B - 1, floor_log2(max_c)) : -B - 1;
  int exp_shared = floor_l2 + 1 + B;
  const double max_s = std::floor(std::ldexp(max_c, -(exp_shared - B - N)) + 0.5);
  if (max_s == double(1 << N)) ++exp_shared;  // rounding carried: one more bit of exponent
  auto mantissa = [&](double v) {
    return uint32_t(std::floor(std::ldexp(v, -(exp_shared - B - N)) + 0.5));
  };
  return mantissa(rc) | (mantissa(gc) << 9) | (mantissa(bc) << 18) |
         (uint32_t(exp_shared) << 27);
}

Rgb decode_rgb9e5(uint32_t packed) {
  constexpr int N = kRgb9e5MantissaBits, B = kRgb9e5ExponentBias;
  const int e = int(packed >> 27) - B - N;
  return {float(std::ldexp(double(packed & 0x1ff), e)),
          float(std::ldexp(double((packed >> 9) & 0x1ff), e)),
          float(std::ldexp(double((packed >> 18) & 0x1ff), e))};
}

}  // namespace tessera::color

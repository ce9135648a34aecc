// SPDX-License-Identifier: Apache-2.0
// Oklab (Björn Ottosson, 2020): a perceptual space where Euclidean distance tracks perceived
// color difference far better than in sRGB, cheap enough (three cube roots) for per-pixel use.
// The palette quantizer clusters and matches colors here.
#pragma once

#include <cmath>

#include "color/rgb.h"

namespace tessera::color {

struct Oklab {
  float L = 0.0f, a = 0.0f, b = 0.0f;
};

// Linear sRGB (Rec. 709 primaries, D65) -> Oklab, with Ottosson's published matrices.
inline Oklab linear_srgb_to_oklab(const Rgb& c) {
  const double l = 0.4122214708 * c.r + 0.5363325363 * c.g + 0.0514459929 * c.b;
  const double m = 0.2119034982 * c.r + 0.6806995451 * c.g + 0.1073969566 * c.b;
  const double s = 0.0883024619 * c.r + 0.2817188376 * c.g + 0.6299787005 * c.b;
  const double l_ = std::cbrt(l), m_ = std::cbrt(m), s_ = std::cbrt(s);
  return {float(0.2104542553 * l_ + 0.7936177850 * m_ - 0.0040720468 * s_),
          float(1.9779984951 * l_ - 2.4285922050 * m_ + 0.4505937099 * s_),
          float(0.0259040371 * l_ + 0.7827717662 * m_ - 0.8086757660 * s_)};
}

inline Rgb oklab_to_linear_srgb(const Oklab& c) {
  const double l_ = c.L + 0.3963377774 * c.a + 0.2158037573 * c.b;
  const double m_ = c.L - 0.1055613458 * c.a - 0.0638541728 * c.b;
  const double s_ = c.L - 0.0894841775 * c.a - 1.2914855480 * c.b;
  const double l = l_ * l_ * l_, m = m_ * m_ * m_, s = s_ * s_ * s_;
  return {float(4.0767416621 * l - 3.3077115913 * m + 0.2309699292 * s),
          float(-1.2684380046 * l + 2.6097574011 * m - 0.3413193965 * s),
          float(-0.0041960863 * l - 0.7034186147 * m + 1.7076147010 * s)};
}

inline float oklab_distance2(const Oklab& x, const Oklab& y) {
  const float dl = x.L - y.L, da = x.a - y.a, db = x.b - y.b;
  return dl * dl + da * da + db * db;
}

}  // namespace tessera::color

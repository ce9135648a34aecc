// SPDX-License-Identifier: Apache-2.0
// What the renderer benchmarks measure an image by: its RMSE against a reference, in linear
// light, over every pixel and channel.
#pragma once

#include <cmath>
#include <cstddef>

#include "image/image.h"

namespace tessera::bench {

inline double rmse(const ImageRGB& a, const ImageRGB& ref) {
  double s = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = double(a.rgb[i]) - double(ref.rgb[i]);
    s += d * d;
  }
  return std::sqrt(s / double(a.rgb.size()));
}

}  // namespace tessera::bench

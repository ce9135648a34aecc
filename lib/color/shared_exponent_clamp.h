// SPDX-License-Identifier: Apache-2.0
// The channel clamp both shared-exponent formats (RGBE, RGB9E5) start from.
#pragma once

#include <algorithm>

namespace tessera::color {

// `v` as the format can hold it: NaN and negatives become 0 (the comparison form sends NaN there
// too), anything above `max` (the format's largest value) becomes `max`.
inline double clamp_shared_exponent_channel(float v, double max) {
  if (!(v > 0.0f)) return 0.0;
  return std::min(double(v), max);
}

}  // namespace tessera::color

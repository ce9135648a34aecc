// SPDX-License-Identifier: Apache-2.0
// Texture lookup: bilinear (or nearest) filtering with glTF's wrap modes, on linear texels.
#pragma once

#include <cmath>

#include "scene/scene.h"

namespace tessera {

inline int wrap_texel(int i, int n, Texture::Wrap w) {
  switch (w) {
    case Texture::Wrap::kClamp: return i < 0 ? 0 : (i >= n ? n - 1 : i);
    case Texture::Wrap::kMirror: {
      const int period = 2 * n;
      int k = i % period;
      if (k < 0) k += period;
      return k < n ? k : period - 1 - k;
    }
    case Texture::Wrap::kRepeat: break;
  }
  const int k = i % n;
  return k < 0 ? k + n : k;
}

// The texture at (u, v): texel centers at ((x + 0.5) / W, (y + 0.5) / H).
inline Rgb sample_texture(const Texture& t, double u, double v) {
  const std::vector<Rgb>& texels = *t.texels;
  if (!std::isfinite(u) || !std::isfinite(v)) return texels[0];
  // Keep the coordinates small before converting to int (wrapping is periodic anyway).
  const double x = u * t.width - 0.5, y = v * t.height - 0.5;
  if (t.nearest || std::abs(x) > 1e9 || std::abs(y) > 1e9) {
    const double cx = std::clamp(std::floor(u * t.width), -1e9, 1e9), cy = std::clamp(std::floor(v * t.height), -1e9, 1e9);
    return texels[size_t(wrap_texel(int(cy), t.height, t.wrap_t)) * size_t(t.width) +
                    size_t(wrap_texel(int(cx), t.width, t.wrap_s))];
  }
  const double fx = std::floor(x), fy = std::floor(y);
  const float ax = float(x - fx), ay = float(y - fy);
  const int x0 = wrap_texel(int(fx), t.width, t.wrap_s), x1 = wrap_texel(int(fx) + 1, t.width, t.wrap_s);
  const int y0 = wrap_texel(int(fy), t.height, t.wrap_t), y1 = wrap_texel(int(fy) + 1, t.height, t.wrap_t);
  auto at = [&](int xx, int yy) { return texels[size_t(yy) * size_t(t.width) + size_t(xx)]; };
  return (at(x0, y0) * (1 - ax) + at(x1, y0) * ax) * (1 - ay) + (at(x0, y1) * (1 - ax) + at(x1, y1) * ax) * ay;
}

}  // namespace tessera

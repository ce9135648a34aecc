// SPDX-License-Identifier: Apache-2.0
// The textures of diffuse materials at a hit: an image texture's albedo (by the hit's uv) and
// the checker pattern's parity.
#include <bit>
#include <cmath>
#include <cstdint>

#include "render/render_scene_internal.h"
#include "scene/texture_sample.h"

namespace tessera {

Rgb RenderScene::textured_albedo(const Hit& hit, const Material& m) const {
  const auto& t = m.uv_transform;
  const double u = t[0] * hit.tex_u + t[1] * hit.tex_v + t[2], v = t[3] * hit.tex_u + t[4] * hit.tex_v + t[5];
  return m.albedo * sample_texture(textures_[size_t(m.albedo_texture)], u, v);
}

// The checker's coordinate x / s is taken as x * (1 / s) where s is a power of two: the
// reciprocal 2^-k is then exact and x * 2^-k is the same real number as x / 2^k, rounded once
// either way, so the bits are the division's; the divisions were two thirds of the checker's time
// on the Whitted showcase (perf annotate), whose scale is 1. Returns 1 / s for such an s (positive,
// normal, no mantissa bits, its reciprocal normal too), else 0: divide.
double RenderScene::checker_inverse(double scale) {
  const uint64_t bits = std::bit_cast<uint64_t>(scale);
  const uint64_t e = (bits >> 52) & 0x7ff;
  if ((bits >> 63) == 0 && (bits & ((uint64_t(1) << 52) - 1)) == 0 && e >= 1 && e <= 2045) {
    return std::bit_cast<double>((2046 - e) << 52);
  }
  return 0.0;
}

}  // namespace tessera

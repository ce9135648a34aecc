// SPDX-License-Identifier: Apache-2.0
// Deterministic synthetic HDR frames for tests and benchmarks when no rendered frame is at
// hand: they have what a render has that stresses a color pipeline (smooth gradients, very
// bright highlights at 160.0, near-black shadows, a little Monte Carlo-like noise).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "image/image.h"

namespace tessera::color {

namespace synthetic_detail {
// Integer hash -> [0, 1): per-pixel noise that does not depend on evaluation order.
inline float hash01(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return float(x >> 8) * (1.0f / 16777216.0f);
}
}  // namespace synthetic_detail

// A sunset sky: deep blue -> orange -> pale yellow from top to bottom, with a gentle
// horizontal vignette. Smooth everywhere; linear values in [0, 1].
inline ImageRGB make_smooth_gradient(int w, int h) {
  ImageRGB img(w, h);
  const float c0[3] = {0.02f, 0.05f, 0.30f}, c1[3] = {0.90f, 0.35f, 0.08f},
              c2[3] = {1.00f, 0.92f, 0.55f};
  for (int y = 0; y < h; ++y) {
    const float t = h > 1 ? float(y) / float(h - 1) : 0.0f;
    for (int x = 0; x < w; ++x) {
      const float u = w > 1 ? float(x) / float(w - 1) - 0.5f : 0.0f;
      const float vignette = 1.0f - 0.35f * u * u * 4.0f;
      float* p = img.at(x, y);
      for (int c = 0; c < 3; ++c) {
        const float v = t < 0.5f ? c0[c] + (c1[c] - c0[c]) * (t * 2.0f)
                                 : c1[c] + (c2[c] - c1[c]) * (t * 2.0f - 1.0f);
        p[c] = v * vignette;
      }
    }
  }
  return img;
}

// A render-like frame: a sky gradient, a ground plane with a soft shadow, three shaded spheres
// (red, green-ish, gray) with specular highlights reaching 160.0, and 2% per-pixel noise.
inline ImageRGB make_render_like(int w, int h) {
  using synthetic_detail::hash01;
  ImageRGB img(w, h);
  struct Sphere {
    float cx, cy, r, color[3];
  };
  const Sphere spheres[3] = {{0.28f, 0.58f, 0.17f, {0.70f, 0.08f, 0.05f}},
                             {0.55f, 0.52f, 0.21f, {0.20f, 0.55f, 0.25f}},
                             {0.80f, 0.62f, 0.12f, {0.60f, 0.60f, 0.62f}}};
  const float horizon = 0.62f;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float u = (float(x) + 0.5f) / float(w);
      const float v = (float(y) + 0.5f) / float(h);
      float c[3];
      if (v < horizon) {  // sky
        const float t = v / horizon;
        c[0] = 0.25f + 0.55f * t;
        c[1] = 0.40f + 0.45f * t;
        c[2] = 0.95f + 0.10f * t;
      } else {  // ground: warm gray, darker far away, with a soft shadow band
        const float t = (v - horizon) / (1.0f - horizon);
        const float shadow = 1.0f - 0.97f * std::exp(-std::pow((u - 0.5f) * 4.0f, 2.0f)) *
                                        std::exp(-std::pow((t - 0.45f) * 5.0f, 2.0f));
        const float g = (0.08f + 0.5f * t) * shadow;
        c[0] = 0.9f * g;
        c[1] = 0.8f * g;
        c[2] = 0.7f * g;
      }
      for (const Sphere& s : spheres) {
        const float dx = (u - s.cx) / s.r, dy = (v - s.cy) * float(h) / float(w) / s.r;
        const float d2 = dx * dx + dy * dy;
        if (d2 >= 1.0f) continue;
        const float nz = std::sqrt(1.0f - d2);
        // Light from the upper left: Lambert plus a tight Phong lobe that peaks at 160.
        const float lx = -0.45f, ly = -0.55f, lz = 0.70f;
        const float ndl = std::max(0.0f, dx * lx + dy * ly + nz * lz);
        const float rz = 2.0f * ndl * nz - lz;  // reflected light toward the viewer (+z)
        const float spec = 160.0f * std::pow(std::max(0.0f, rz), 400.0f);
        for (int k = 0; k < 3; ++k) c[k] = s.color[k] * (0.03f + 0.97f * ndl) + spec;
      }
      const float n = 1.0f + 0.02f * (hash01(uint32_t(y * w + x)) - 0.5f) * 2.0f;
      float* p = img.at(x, y);
      for (int k = 0; k < 3; ++k) p[k] = c[k] * n;
    }
  }
  return img;
}

}  // namespace tessera::color

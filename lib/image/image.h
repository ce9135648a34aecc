// SPDX-License-Identifier: Apache-2.0
// A float HDR RGB image in linear light, row-major, top row first: the currency between
// the renderer, the farm (assembled from tiles) and the color code.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace tessera {

struct ImageRGB {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;  // 3 * width * height, interleaved R, G, B

  ImageRGB() = default;
  ImageRGB(int w, int h) : width(w), height(h), rgb(size_t(3) * size_t(w) * size_t(h), 0.0f) {}

  size_t index(int x, int y) const { return (size_t(y) * size_t(width) + size_t(x)) * 3; }
  float* at(int x, int y) { return &rgb[index(x, y)]; }
  const float* at(int x, int y) const { return &rgb[index(x, y)]; }
  size_t pixel_count() const { return size_t(width) * size_t(height); }
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Small pixel value types shared by the color code.
#pragma once

#include <algorithm>
#include <cstdint>

namespace tessera::color {

// A linear-light (or, where a function says so, sRGB-encoded) float color.
struct Rgb {
  float r = 0.0f, g = 0.0f, b = 0.0f;

  float operator[](int i) const { return i == 0 ? r : i == 1 ? g : b; }
  float& operator[](int i) { return i == 0 ? r : i == 1 ? g : b; }
  float max_component() const { return std::max({r, g, b}); }
  float min_component() const { return std::min({r, g, b}); }
  bool operator==(const Rgb&) const = default;
};

// An 8-bit sRGB-encoded color: a PNG pixel or palette entry.
struct Srgb8 {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Srgb8&) const = default;
};

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
#include "color/palette_fade.h"

#include <cstdio>

#include "color/color_error.h"
#include "color/png_io.h"
#include "color/srgb.h"

namespace tessera::color {

std::vector<Srgb8> fade_palette(const std::vector<Srgb8>& palette, double factor) {
  std::vector<Srgb8> out;
  out.reserve(palette.size());
  for (const Srgb8& c : palette) {
    const Rgb lin = srgb8_to_linear(c);
    out.push_back({linear_to_srgb8(lin.r * factor), linear_to_srgb8(lin.g * factor),
                   linear_to_srgb8(lin.b * factor)});
  }
  return out;
}

std::string frame_path(const std::string& pattern, int frame) {
  std::string base = pattern;
  size_t end = base.rfind('#');
  if (end == std::string::npos) {
    const size_t slash = base.find_last_of('/');
    const size_t dot = base.find_last_of('.');
    const size_t at = dot != std::string::npos && (slash == std::string::npos || dot > slash)
                          ? dot
                          : base.size();
    base.insert(at, "_####");
    end = base.rfind('#');
  }
  size_t begin = end;
  while (begin > 0 && base[begin - 1] == '#') --begin;
  const int digits = int(end - begin + 1);
  char number[32];
  std::snprintf(number, sizeof(number), "%0*d", digits, frame);
  return base.substr(0, begin) + number + base.substr(end + 1);
}

std::vector<std::string> write_palette_fade(const std::string& input, int frames,
                                            const std::string& pattern) {
  if (frames < 2) throw ColorError("palette-fade needs --frames >= 2");
  int bit_depth = 8;
  IndexedImage image = read_png_indexed(input, &bit_depth);
  const std::vector<Srgb8> original = image.palette;
  std::vector<std::string> written;
  for (int f = 0; f < frames; ++f) {
    const double factor = 1.0 - double(f) / double(frames - 1);
    image.palette = fade_palette(original, factor);
    const std::string path = frame_path(pattern, f + 1);
    write_png_indexed(path, image, bit_depth);
    written.push_back(path);
  }
  return written;
}

}  // namespace tessera::color

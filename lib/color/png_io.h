// SPDX-License-Identifier: Apache-2.0
// PNG files through libpng: 24/32-bit truecolor and indexed (PLTE) images, and a reader that
// returns what the file stores (indices stay indices) so palette animation can keep them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "color/rgb.h"

namespace tessera::color {

// 8-bit sRGB truecolor pixels, top row first: width * height * channels bytes.
struct Rgb8Image {
  int width = 0;
  int height = 0;
  int channels = 3;  // 3 (RGB) or 4 (RGBA)
  std::vector<uint8_t> pixels;
};

// One palette index per pixel (one byte each in memory, whatever the file's bit depth).
struct IndexedImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> indices;
  std::vector<Srgb8> palette;  // at most 256 entries
  std::vector<uint8_t> alpha;  // tRNS entries, empty when opaque
};

// The smallest PNG bit depth (1, 2, 4 or 8) that indexes `colors` palette entries.
int palette_bit_depth(int colors);

// Writes an RGB (channels 3) or RGBA (channels 4) 8-bit PNG tagged sRGB. Throws ColorError.
void write_png(const std::string& path, const Rgb8Image& image);
// The same PNG in memory (the coordinator's monitor serves previews without files). Throws ColorError.
std::string encode_png(const Rgb8Image& image);

// Writes an indexed PNG (PLTE, tRNS when alpha is set) at palette_bit_depth(palette.size()),
// or at bit_depth when it is given and large enough. Throws ColorError.
void write_png_indexed(const std::string& path, const IndexedImage& image, int bit_depth = 0);

// Reads an indexed PNG without expanding the palette; *bit_depth receives the file's depth.
// Throws ColorError if the file is not color type 3 (palette).
IndexedImage read_png_indexed(const std::string& path, int* bit_depth = nullptr);

// Reads any PNG as 8-bit RGB (palette expanded, gray expanded, 16-bit reduced, alpha dropped).
Rgb8Image read_png_rgb8(const std::string& path);

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// RGB565: 16 bits per pixel, 5 bits red, 6 green, 5 blue, of sRGB-encoded values, in a BMP
// with BI_BITFIELDS masks (BITMAPV4HEADER, color space LCS_sRGB), which Windows, browsers,
// GIMP and OpenImageIO read. Hand-written: Debian has no BMP-writing library worth a
// dependency, and the format is a fixed header plus rows.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "color/dither.h"
#include "color/rgb.h"
#include "image/image.h"

namespace tessera::color {

// Quantizes sRGB-encoded [0, 1] values as floor(v * levels + threshold), clamped, where
// levels is 31 or 63 and threshold in (0, 1) comes from ordered_threshold (0.5 = rounding).
uint16_t pack_565(const Rgb& srgb_encoded, float threshold);

// The encoded values a 565 pixel stands for: r/31, g/63, b/31.
Rgb unpack_565(uint16_t p);

// The whole image with an ordered dither (kNone, kBayer or kBlueNoise; same threshold for the
// three channels so that grays stay gray). Throws ColorError for kFloydSteinberg.
std::vector<uint16_t> quantize_565(const ImageRGB& srgb_encoded, DitherMethod dither);

// Rows top first in memory; written bottom-up as BMP readers expect. Throws ColorError.
void write_bmp565(const std::string& path, int width, int height,
                  const std::vector<uint16_t>& pixels);

// Reads a 16-bit BI_BITFIELDS 5/6/5 BMP (what write_bmp565 writes). Throws ColorError.
std::vector<uint16_t> read_bmp565(const std::string& path, int* width, int* height);

}  // namespace tessera::color

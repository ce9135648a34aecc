// SPDX-License-Identifier: Apache-2.0
// RGBE: Greg Ward's Radiance pixel, three 8-bit mantissas and a shared exponent byte (biased
// by 128), and the Radiance .hdr file that stores it. Hand-written: the format is a page of
// spec, Debian has no small library for it, and OpenImageIO (a heavy dependency) is only
// used as an independent reader in the tests.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "color/rgb.h"

namespace tessera::color {

using Rgbe = std::array<uint8_t, 4>;

// The largest encodable channel value: mantissa 255 with exponent byte 255 = 255 * 2^119.
inline constexpr double kRgbeMax = 255.0 * 0x1p119;

// Negatives and NaN -> 0; values above kRgbeMax (including +Inf) -> kRgbeMax; a pixel whose
// largest channel is below 2^-128 is written as black (0,0,0,0) as Radiance does.
// The exponent is Radiance's (frexp of the largest channel, so its mantissa is in
// [128, 256)); mantissas are rounded to nearest and capped at 255. (Radiance's own encoder
// truncates and its decoder adds 0.5; rounding lets the plain decoders, m * 2^(e-136), used by
// OpenImageIO, stb_image and Walter's rgbe.c, reconstruct every channel within 2^-8 of the
// largest one.)
Rgbe encode_rgbe(const Rgb& c);

// m * 2^(e - 136) per channel; exponent byte 0 is black.
Rgb decode_rgbe(const Rgbe& p);

// Writes "#?RADIANCE", FORMAT=32-bit_rle_rgbe, "-Y H +X W" (top row first), then the scanlines
// with the adaptive run-length encoding of Radiance (flat for widths outside [8, 32767]).
void write_radiance_hdr(const std::string& path, int width, int height,
                        const std::vector<Rgbe>& pixels);

// Reads a -Y +X Radiance file, flat or run-length encoded (new style). Throws ColorError.
std::vector<Rgbe> read_radiance_hdr(const std::string& path, int* width, int* height);

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// Palette animation: a fade to black made by rewriting only the PLTE chunk, the pixels'
// indices (and so the IDAT data) untouched, as 8-bit-era games and demos did it.
#pragma once

#include <string>
#include <vector>

#include "color/rgb.h"

namespace tessera::color {

// The palette scaled by `factor` (0..1) in linear light: decode sRGB, multiply, re-encode
// and round, so a 50% step halves the emitted light rather than the code values.
std::vector<Srgb8> fade_palette(const std::vector<Srgb8>& palette, double factor);

// Replaces the last run of '#' in pattern by the zero-padded frame number (at least as many
// digits as '#'s). Without '#', "_####" is inserted before the extension.
std::string frame_path(const std::string& pattern, int frame);

// Reads the indexed PNG `input` and writes `frames` (>= 2) PNGs: frame 1 is the original
// palette, frame `frames` is black, in between the light fades linearly. Every frame keeps
// the input's indices, bit depth and transparency. Returns the written paths. Throws ColorError.
std::vector<std::string> write_palette_fade(const std::string& input, int frames,
                                            const std::string& pattern);

}  // namespace tessera::color

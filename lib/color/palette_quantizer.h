// SPDX-License-Identifier: Apache-2.0
// Palette quantization: at most N (2..256) colors for an image, an index per pixel.
//
// The palette is seeded by a variance-minimizing median cut in Oklab (each step splits the box
// of largest weighted squared error, along its axis of largest variance, at the position that
// minimizes the two halves' summed error, as Wu's quantizer does), then refined by weighted
// k-means (Lloyd) in Oklab over the image's distinct 8-bit colors. Pixels are mapped to the
// nearest entry in Oklab, or with Floyd-Steinberg error diffusion done in linear light with
// serpentine scanning. Hand-written: Debian's only quantizer libraries (libimagequant) are GPL.
#pragma once

#include <cstdint>
#include <vector>

#include "color/dither.h"
#include "color/oklab.h"
#include "color/png_io.h"
#include "color/rgb.h"
#include "image/image.h"

namespace tessera::color {

struct QuantizerOptions {
  int max_colors = 256;    // 2..256
  DitherMethod dither = DitherMethod::kNone;  // kNone or kFloydSteinberg
  int kmeans_iterations = 16;  // upper bound; stops earlier once the error stops improving
};

// Nearest-color search in Oklab: entries sorted by L, scanned outward from the query's L
// and cut off once the L difference alone exceeds the best distance.
class OklabNearest {
 public:
  explicit OklabNearest(const std::vector<Oklab>& colors);
  int nearest(const Oklab& q) const;  // index into the constructor's vector

 private:
  std::vector<Oklab> sorted_;
  std::vector<int> original_index_;
};

// Builds a palette of at most max_colors distinct entries for these 8-bit sRGB pixels. When
// the pixels have no more distinct colors than that, the palette is exactly those colors.
std::vector<Srgb8> build_palette(const std::vector<Srgb8>& pixels, int max_colors,
                                 int kmeans_iterations = 16);

// Each pixel's nearest palette entry in Oklab.
std::vector<uint8_t> map_to_palette(const std::vector<Srgb8>& pixels,
                                    const std::vector<Srgb8>& palette);

// Floyd-Steinberg in linear light, serpentine: the error between the wanted linear color
// (pixel + diffused error) and the chosen entry's linear color is spread 7/16, 3/16, 5/16,
// 1/16 forward. The diffused error is capped per channel at 0.03 + 0.25 * pixel value, so it
// cannot run away where the image leaves the palette's hull, and each pixel takes it in
// proportion to how flat the undithered mapping is around it (squared share of its 8
// neighbors with its own index): full dithering inside bands, little in texture and render
// noise, where it would only add noise (the idea of libimagequant's dither map).
std::vector<uint8_t> map_floyd_steinberg(const ImageRGB& display_linear,
                                         const std::vector<Srgb8>& palette);

// The whole pipeline: display_linear is tone-mapped linear light in [0, 1].
IndexedImage quantize_palette(const ImageRGB& display_linear, const QuantizerOptions& options);

// 8-bit sRGB pixels of a display-linear image (rounded to nearest).
std::vector<Srgb8> to_srgb8_pixels(const ImageRGB& display_linear);

}  // namespace tessera::color

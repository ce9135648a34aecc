// SPDX-License-Identifier: Apache-2.0
// The conversion pipeline: one float HDR frame -> one output file in a chosen format, with
// the report of what the conversion lost.
//
//   LDR formats (rgba8, rgb8, rgb565, palette): sanitize -> exposure -> tone map (linear) ->
//     sRGB transfer -> quantize (optionally dithered). Error against the unquantized
//     tone-mapped sRGB image: PSNR and max abs error in 8-bit code values.
//   HDR formats (rgbe, rgb9e5, exr-half, exr-float): sanitize -> exposure, kept in linear light
//     (tone mapping would throw away the range these formats exist to keep). Error: max and
//     mean relative error in linear light against the exposed input, plus PSNR / max abs error
//     of the tone-mapped decoded image against the tone-mapped input, so all rows of a table
//     compare on one scale.
//   Pixels with a NaN or Inf input are left out of the error measures (they have no true value
//   to compare with); the report counts them instead.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "color/dither.h"
#include "color/image_metrics.h"
#include "color/input_sanitizer.h"
#include "color/png_io.h"
#include "color/tonemap.h"
#include "image/exr_io.h"
#include "image/image.h"

namespace tessera::color {

enum class OutputFormat { kRgba8, kRgb8, kRgb565, kPalette, kRgbe, kRgb9e5, kExrHalf, kExrFloat };

std::string_view format_name(OutputFormat f);
std::optional<OutputFormat> parse_format(std::string_view name);
// .png -> rgb8, .bmp -> rgb565, .hdr/.rgbe/.pic -> rgbe, .dds -> rgb9e5, .exr -> exr-float.
std::optional<OutputFormat> format_from_extension(std::string_view path);
bool is_hdr_format(OutputFormat f);

struct ConvertOptions {
  ToneMapSettings tonemap;
  OutputFormat format = OutputFormat::kRgb8;
  int colors = 256;  // palette only, 2..256
  DitherMethod dither = DitherMethod::kNone;
  ExrCompression exr_compression = ExrCompression::kZip;  // EXR formats only; lossless
};

// Throws ColorError naming the problem when options do not fit together (e.g. a Bayer dither
// on a palette, or any dither on an HDR format).
void validate(const ConvertOptions& options);

struct ConversionReport {
  std::string path;
  OutputFormat format = OutputFormat::kRgb8;
  int width = 0, height = 0;
  int bits_per_pixel = 0;   // of the pixel format (palette: the PNG bit depth)
  uint64_t file_bytes = 0;  // what landed on disk, headers and compression included
  double encode_seconds = 0.0;
  ToneMapSettings tonemap;  // as applied (white: the one used, for Reinhard)
  DitherMethod dither = DitherMethod::kNone;
  int palette_colors = 0;  // entries actually used; 0 for other formats
  LdrError ldr;
  std::optional<HdrError> hdr;  // HDR formats only
  InputStats input;             // values that went through the sanitizing policy
};

// Converts and writes. Throws ColorError / ExrError naming the path on failure.
ConversionReport convert_image(const ImageRGB& hdr, const std::string& path,
                               const ConvertOptions& options);

// sRGB-encoded [0, 1] floats -> 8-bit pixels (channels 3 or 4, alpha opaque), with the ordered
// dither's thresholds (none: round to nearest); `decoded` (may be null) receives q / 255.
Rgb8Image quantize_rgb8(const ImageRGB& srgb, int channels, DitherMethod dither, ImageRGB* decoded);
// What convert_image writes to an 8-bit PNG without dithering: sanitize, expose, tone map, sRGB,
// quantize. The coordinator's monitor previews frames with it, so a preview equals the PNG
// `tessera convert` makes of the same frame.
Rgb8Image tonemap_to_rgb8(const ImageRGB& hdr, const ToneMapSettings& tonemap);

// The one-line human report and its machine-readable form (PSNR of a lossless output is null).
std::string report_text(const ConversionReport& r);
nlohmann::json report_json(const ConversionReport& r);

}  // namespace tessera::color

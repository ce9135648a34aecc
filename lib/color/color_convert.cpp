// SPDX-License-Identifier: Apache-2.0
#include "color/color_convert.h"

#include <half.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "color/bmp565.h"
#include "color/color_error.h"
#include "color/dds_rgb9e5.h"
#include "color/palette_quantizer.h"
#include "color/png_io.h"
#include "color/rgb9e5.h"
#include "color/rgbe.h"
#include "color/srgb.h"
#include "image/exr_io.h"

namespace tessera::color {

namespace {

constexpr OutputFormat kAllFormats[] = {
    OutputFormat::kRgba8,   OutputFormat::kRgb8,   OutputFormat::kRgb565,  OutputFormat::kPalette,
    OutputFormat::kRgbe,    OutputFormat::kRgb9e5, OutputFormat::kExrHalf, OutputFormat::kExrFloat};

std::string lower_extension(std::string_view path) {
  std::string ext = std::filesystem::path(std::string(path)).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

// The half conversion write_exr performs (clamp to +-65504, NaN -> 0), in memory, so the
// report measures exactly what the file holds.
float through_half(float v) {
  if (std::isnan(v)) return 0.0f;
  return float(half(std::clamp(v, -65504.0f, 65504.0f)));
}

}  // namespace

Rgb8Image quantize_rgb8(const ImageRGB& srgb, int channels, DitherMethod dither, ImageRGB* decoded) {
  Rgb8Image png;
  png.width = srgb.width;
  png.height = srgb.height;
  png.channels = channels;
  png.pixels.resize(srgb.pixel_count() * size_t(png.channels));
  if (decoded) *decoded = ImageRGB(srgb.width, srgb.height);
  for (int y = 0; y < srgb.height; ++y) {
    for (int x = 0; x < srgb.width; ++x) {
      const float t = ordered_threshold(dither, x, y);
      const size_t p = size_t(y) * size_t(srgb.width) + size_t(x);
      for (int c = 0; c < 3; ++c) {
        const float v = srgb.rgb[3 * p + size_t(c)];
        const uint8_t q = uint8_t(std::clamp(std::floor(v * 255.0f + t), 0.0f, 255.0f));
        png.pixels[p * size_t(png.channels) + size_t(c)] = q;
        if (decoded) decoded->rgb[3 * p + size_t(c)] = float(q) / 255.0f;
      }
      if (png.channels == 4) png.pixels[p * 4 + 3] = 255;
    }
  }
  return png;
}

Rgb8Image tonemap_to_rgb8(const ImageRGB& hdr, const ToneMapSettings& tonemap) {
  return quantize_rgb8(srgb_encode_image(tonemap_image(hdr, tonemap)), 3, DitherMethod::kNone, nullptr);
}

namespace {

struct Encoded {
  ImageRGB decoded;  // LDR: sRGB-encoded [0, 1]; HDR: linear
  int bits_per_pixel = 0;
  int palette_colors = 0;
};

Encoded encode_ldr(const ImageRGB& srgb, const ImageRGB& display_linear, const std::string& path,
                   const ConvertOptions& o) {
  Encoded e;
  e.decoded = ImageRGB(srgb.width, srgb.height);
  switch (o.format) {
    case OutputFormat::kRgb8:
    case OutputFormat::kRgba8: {
      const Rgb8Image png = quantize_rgb8(srgb, o.format == OutputFormat::kRgba8 ? 4 : 3, o.dither, &e.decoded);
      write_png(path, png);
      e.bits_per_pixel = png.channels * 8;
      break;
    }
    case OutputFormat::kRgb565: {
      const std::vector<uint16_t> px = quantize_565(srgb, o.dither);
      for (size_t p = 0; p < px.size(); ++p) {
        const Rgb d = unpack_565(px[p]);
        for (int c = 0; c < 3; ++c) e.decoded.rgb[3 * p + size_t(c)] = d[c];
      }
      write_bmp565(path, srgb.width, srgb.height, px);
      e.bits_per_pixel = 16;
      break;
    }
    case OutputFormat::kPalette: {
      const IndexedImage img =
          quantize_palette(display_linear, QuantizerOptions{o.colors, o.dither, 16});
      for (size_t p = 0; p < img.indices.size(); ++p) {
        const Srgb8& c = img.palette[img.indices[p]];
        e.decoded.rgb[3 * p] = float(c.r) / 255.0f;
        e.decoded.rgb[3 * p + 1] = float(c.g) / 255.0f;
        e.decoded.rgb[3 * p + 2] = float(c.b) / 255.0f;
      }
      write_png_indexed(path, img);
      e.bits_per_pixel = palette_bit_depth(int(img.palette.size()));
      e.palette_colors = int(img.palette.size());
      break;
    }
    default:
      throw ColorError("not an LDR format");
  }
  return e;
}

Encoded encode_hdr(const ImageRGB& linear, const std::string& path, const ConvertOptions& o) {
  Encoded e;
  e.decoded = ImageRGB(linear.width, linear.height);
  const size_t n = linear.pixel_count();
  switch (o.format) {
    case OutputFormat::kRgbe: {
      std::vector<Rgbe> px(n);
      for (size_t p = 0; p < n; ++p) {
        px[p] = encode_rgbe({linear.rgb[3 * p], linear.rgb[3 * p + 1], linear.rgb[3 * p + 2]});
        const Rgb d = decode_rgbe(px[p]);
        for (int c = 0; c < 3; ++c) e.decoded.rgb[3 * p + size_t(c)] = d[c];
      }
      write_radiance_hdr(path, linear.width, linear.height, px);
      e.bits_per_pixel = 32;
      break;
    }
    case OutputFormat::kRgb9e5: {
      std::vector<uint32_t> px(n);
      for (size_t p = 0; p < n; ++p) {
        px[p] = encode_rgb9e5({linear.rgb[3 * p], linear.rgb[3 * p + 1], linear.rgb[3 * p + 2]});
        const Rgb d = decode_rgb9e5(px[p]);
        for (int c = 0; c < 3; ++c) e.decoded.rgb[3 * p + size_t(c)] = d[c];
      }
      write_dds_rgb9e5(path, linear.width, linear.height, px);
      e.bits_per_pixel = 32;
      break;
    }
    case OutputFormat::kExrHalf:
      std::transform(linear.rgb.begin(), linear.rgb.end(), e.decoded.rgb.begin(), through_half);
      write_exr(path, linear, {{"software", std::string("tessera convert")}}, ExrPixelType::kHalf, {},
                o.exr_compression);
      e.bits_per_pixel = 48;
      break;
    case OutputFormat::kExrFloat:
      e.decoded = linear;
      write_exr(path, linear, {{"software", std::string("tessera convert")}}, ExrPixelType::kFloat, {},
                o.exr_compression);
      e.bits_per_pixel = 96;
      break;
    default:
      throw ColorError("not an HDR format");
  }
  return e;
}

std::string human_bytes(uint64_t b) {
  char buf[32];
  if (b < 1024) {
    std::snprintf(buf, sizeof(buf), "%llu B", static_cast<unsigned long long>(b));
  } else if (b < 1024 * 1024) {
    std::snprintf(buf, sizeof(buf), "%.1f KiB", double(b) / 1024.0);
  } else {
    std::snprintf(buf, sizeof(buf), "%.2f MiB", double(b) / (1024.0 * 1024.0));
  }
  return buf;
}

}  // namespace

std::string_view format_name(OutputFormat f) {
  switch (f) {
    case OutputFormat::kRgba8: return "rgba8";
    case OutputFormat::kRgb8: return "rgb8";
    case OutputFormat::kRgb565: return "rgb565";
    case OutputFormat::kPalette: return "palette";
    case OutputFormat::kRgbe: return "rgbe";
    case OutputFormat::kRgb9e5: return "rgb9e5";
    case OutputFormat::kExrHalf: return "exr-half";
    case OutputFormat::kExrFloat: return "exr-float";
  }
  return "?";
}

std::optional<OutputFormat> parse_format(std::string_view name) {
  for (OutputFormat f : kAllFormats) {
    if (format_name(f) == name) return f;
  }
  return std::nullopt;
}

std::optional<OutputFormat> format_from_extension(std::string_view path) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") return OutputFormat::kRgb8;
  if (ext == ".bmp") return OutputFormat::kRgb565;
  if (ext == ".hdr" || ext == ".rgbe" || ext == ".pic") return OutputFormat::kRgbe;
  if (ext == ".dds") return OutputFormat::kRgb9e5;
  if (ext == ".exr") return OutputFormat::kExrFloat;
  return std::nullopt;
}

bool is_hdr_format(OutputFormat f) {
  return f == OutputFormat::kRgbe || f == OutputFormat::kRgb9e5 || f == OutputFormat::kExrHalf ||
         f == OutputFormat::kExrFloat;
}

void validate(const ConvertOptions& o) {
  if (o.format == OutputFormat::kPalette && (o.colors < 2 || o.colors > 256)) {
    throw ColorError("--colors must be between 2 and 256");
  }
  if (!std::isfinite(o.tonemap.exposure_ev) || std::abs(o.tonemap.exposure_ev) > 64.0f) {
    throw ColorError("--exposure must be a finite number of stops in [-64, 64]");
  }
  if (!std::isfinite(o.tonemap.white) || o.tonemap.white < 0.0f) {
    throw ColorError("--white must be a positive number (or 0 for the brightest pixel)");
  }
  const DitherMethod d = o.dither;
  if (d == DitherMethod::kNone) return;
  if (is_hdr_format(o.format)) {
    throw ColorError(std::string("--dither does not apply to ") + std::string(format_name(o.format)));
  }
  if (o.format == OutputFormat::kPalette && d != DitherMethod::kFloydSteinberg) {
    throw ColorError("palette output supports --dither none or floyd-steinberg");
  }
  if (o.format != OutputFormat::kPalette && d == DitherMethod::kFloydSteinberg) {
    throw ColorError(std::string(format_name(o.format)) +
                     " supports --dither none, bayer or blue-noise");
  }
}

ConversionReport convert_image(const ImageRGB& hdr, const std::string& path,
                               const ConvertOptions& o) {
  validate(o);
  if (hdr.width <= 0 || hdr.height <= 0 || hdr.rgb.size() != hdr.pixel_count() * 3) {
    throw ColorError("cannot write " + path + ": empty or malformed image");
  }
  ConversionReport r;
  r.path = path;
  r.format = o.format;
  r.width = hdr.width;
  r.height = hdr.height;
  r.tonemap = o.tonemap;
  r.dither = o.dither;
  r.input = count_special_values(hdr);
  // Non-finite input pixels have no true value to compare with: left out of the error.
  const std::vector<uint8_t> mask = finite_pixel_mask(hdr);
  const std::vector<uint8_t>* measured = r.input.nan + r.input.pos_inf + r.input.neg_inf ? &mask : nullptr;

  const auto start = std::chrono::steady_clock::now();
  Encoded e;
  ImageRGB reference_srgb;  // unquantized tone-mapped image, sRGB-encoded
  ImageRGB decoded_srgb;
  if (!is_hdr_format(o.format)) {
    double white = 1.0;
    const ImageRGB display = tonemap_image(hdr, o.tonemap, &white);
    r.tonemap.white = float(white);
    reference_srgb = srgb_encode_image(display);
    e = encode_ldr(reference_srgb, display, path, o);
    r.encode_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    decoded_srgb = std::move(e.decoded);
  } else {
    const bool signed_values = o.format == OutputFormat::kExrHalf || o.format == OutputFormat::kExrFloat;
    const ImageRGB linear = expose_image(hdr, o.tonemap.exposure_ev, signed_values);
    e = encode_hdr(linear, path, o);
    r.encode_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    r.hdr = hdr_relative_error(linear, e.decoded, measured);
    // Same tone curve for both sides (exposure already applied, same white point).
    ToneMapSettings view = o.tonemap;
    view.exposure_ev = 0.0f;
    double white = 1.0;
    reference_srgb = srgb_encode_image(tonemap_image(linear, view, &white));
    view.white = float(white);
    r.tonemap.white = float(white);
    decoded_srgb = srgb_encode_image(tonemap_image(e.decoded, view));
  }
  r.bits_per_pixel = e.bits_per_pixel;
  r.palette_colors = e.palette_colors;
  r.ldr = ldr_error(reference_srgb, decoded_srgb, measured);
  std::error_code ec;
  r.file_bytes = std::filesystem::file_size(path, ec);
  if (ec) r.file_bytes = 0;
  return r;
}

std::string report_text(const ConversionReport& r) {
  char buf[512];
  std::string s;
  const double pixels = double(r.width) * double(r.height);
  std::snprintf(buf, sizeof(buf), "%s %s %dx%d: %d bpp, %s (%.2f bpp on disk)",
                std::string(format_name(r.format)).c_str(), r.path.c_str(), r.width, r.height,
                r.bits_per_pixel, human_bytes(r.file_bytes).c_str(),
                pixels > 0 ? double(r.file_bytes) * 8.0 / pixels : 0.0);
  s += buf;
  if (r.hdr) {
    std::snprintf(buf, sizeof(buf), ", rel err max %.3g mean %.3g (linear)", r.hdr->max_rel,
                  r.hdr->mean_rel);
    s += buf;
  }
  if (std::isinf(r.ldr.psnr_db)) {
    s += ", PSNR inf (lossless)";
  } else {
    std::snprintf(buf, sizeof(buf), ", PSNR %.2f dB, max abs err %.2f/255", r.ldr.psnr_db,
                  r.ldr.max_abs);
    s += buf;
  }
  if (r.hdr) s += " after tone mapping";
  std::snprintf(buf, sizeof(buf), " | tonemap %s, exposure %+.2f EV",
                std::string(tonemap_name(r.tonemap.op)).c_str(), double(r.tonemap.exposure_ev));
  s += buf;
  if (r.tonemap.op == ToneMapOperator::kReinhard) {
    std::snprintf(buf, sizeof(buf), ", white %.4g", double(r.tonemap.white));
    s += buf;
  }
  if (r.format == OutputFormat::kPalette) {
    std::snprintf(buf, sizeof(buf), ", %d colors", r.palette_colors);
    s += buf;
  }
  if (r.dither != DitherMethod::kNone) s += ", dither " + std::string(dither_name(r.dither));
  std::snprintf(buf, sizeof(buf), " | %.1f ms", r.encode_seconds * 1e3);
  s += buf;
  if (r.input.total() > 0) {
    std::snprintf(buf, sizeof(buf),
                  " | input had %llu NaN, %llu +Inf, %llu -Inf, %llu negative values (sanitized)",
                  static_cast<unsigned long long>(r.input.nan),
                  static_cast<unsigned long long>(r.input.pos_inf),
                  static_cast<unsigned long long>(r.input.neg_inf),
                  static_cast<unsigned long long>(r.input.negative));
    s += buf;
  }
  return s;
}

nlohmann::json report_json(const ConversionReport& r) {
  const double pixels = double(r.width) * double(r.height);
  nlohmann::json j = {
      {"path", r.path},
      {"format", format_name(r.format)},
      {"width", r.width},
      {"height", r.height},
      {"bits_per_pixel", r.bits_per_pixel},
      {"file_bytes", r.file_bytes},
      {"file_bits_per_pixel", pixels > 0 ? double(r.file_bytes) * 8.0 / pixels : 0.0},
      {"encode_ms", r.encode_seconds * 1e3},
      {"tonemap", tonemap_name(r.tonemap.op)},
      {"exposure_ev", r.tonemap.exposure_ev},
      {"dither", dither_name(r.dither)},
      {"psnr_db", std::isfinite(r.ldr.psnr_db) ? nlohmann::json(r.ldr.psnr_db) : nlohmann::json()},
      {"max_abs_error_8bit", r.ldr.max_abs},
      {"rmse_8bit", r.ldr.rmse},
      {"input", {{"nan", r.input.nan}, {"pos_inf", r.input.pos_inf}, {"neg_inf", r.input.neg_inf},
                 {"negative", r.input.negative}}},
  };
  if (r.tonemap.op == ToneMapOperator::kReinhard) j["white"] = r.tonemap.white;
  if (r.format == OutputFormat::kPalette) j["colors"] = r.palette_colors;
  if (r.hdr) {
    j["max_rel_error"] = r.hdr->max_rel;
    j["mean_rel_error"] = r.hdr->mean_rel;
  }
  return j;
}

}  // namespace tessera::color

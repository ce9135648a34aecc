// SPDX-License-Identifier: Apache-2.0
#include <cctype>
#include <filesystem>
#include "color/output_options.h"

#include "color/color_error.h"

namespace tessera::color {

ConvertOptions resolve_output_options(const OutputOptions& o, const std::string& out_path) {
  ConvertOptions c;
  const auto op = parse_tonemap(o.tonemap);
  if (!op) throw ColorError("unknown --tonemap " + o.tonemap);
  c.tonemap = {*op, o.exposure_ev, o.white};
  const auto dither = parse_dither(o.dither);
  if (!dither) throw ColorError("unknown --dither " + o.dither);
  c.dither = *dither;
  if (!o.format.empty()) {
    const auto f = parse_format(o.format);
    if (!f) throw ColorError("unknown --format " + o.format);
    c.format = *f;
  } else {
    const auto f = format_from_extension(out_path);
    if (!f) {
      throw ColorError("cannot tell the format of " + out_path +
                       " from its extension (.png .bmp .hdr .dds .exr); pass --format");
    }
    c.format = *f;
    // `--colors N` on a .png means an indexed PNG; so does a Floyd-Steinberg request.
    if (c.format == OutputFormat::kRgb8 &&
        (o.colors != 0 || c.dither == DitherMethod::kFloydSteinberg)) {
      c.format = OutputFormat::kPalette;
    }
  }
  if (o.colors != 0 && c.format != OutputFormat::kPalette) {
    throw ColorError("--colors applies to --format palette only");
  }
  c.colors = o.colors != 0 ? o.colors : 256;
  try {
    c.exr_compression = parse_exr_compression(o.exr_compression);
  } catch (const ExrError& e) {
    throw ColorError(std::string("--exr-compression: ") + e.what());
  }
  validate(c);
  return c;
}

ConversionReport write_output(const ImageRGB& image, const std::string& out_path,
                              const OutputOptions& o, std::ostream& report_out, const std::string& report_path) {
  const ConvertOptions c = resolve_output_options(o, out_path);
  ConversionReport r = convert_image(image, out_path, c);
  if (!report_path.empty()) r.path = report_path;
  if (o.report == "json") {
    report_out << report_json(r).dump() << "\n";
  } else {
    report_out << report_text(r) << "\n";
  }
  return r;
}

bool is_float_exr_output(const OutputOptions& options, const std::string& out_path) {
  if (!options.format.empty()) return options.format == "exr-float";
  std::string ext = std::filesystem::path(out_path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".exr";
}

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// The output options of `tessera convert`, reusable by any command that produces a frame
// (`tessera render`, `tessera submit`): a plain struct the program fills (the client's
// command-line flags do, in client/output_flags.h), resolved here against the output path.
//
//   OutputOptions out;               // filled from --tonemap, --format, ...
//   ... after rendering ...
//   write_output(image, out_path, out, std::cout);  // prints the one-line report
#pragma once

#include <ostream>
#include <string>

#include "color/color_convert.h"
#include "image/image.h"

namespace tessera::color {

struct OutputOptions {
  std::string tonemap = "clamp";  // clamp | reinhard | aces | pbr-neutral
  float exposure_ev = 0.0f;
  float white = 0.0f;        // Reinhard white point; 0 = brightest pixel
  std::string format;        // empty: from the output file's extension
  int colors = 0;            // 0: not given (256 for palette); given with .png: palette
  std::string dither = "none";  // none | bayer | blue-noise | floyd-steinberg
  std::string report = "text";  // text | json
  std::string exr_compression = "zip";  // EXR outputs: none | rle | zips | zip | piz (image/exr_io.h)
};

// Turns the parsed strings into ConvertOptions for this output path; throws ColorError when
// the format cannot be told from the extension or options conflict.
ConvertOptions resolve_output_options(const OutputOptions& options, const std::string& out_path);

// True when out_path with these options is a plain 32-bit float EXR. Renderers write those
// themselves so the EXR keeps their header attributes (spp, rays, render time).
bool is_float_exr_output(const OutputOptions& options, const std::string& out_path);

// Converts, writes out_path, prints the report line (text or JSON) to report_out and returns
// it. Throws ColorError / ExrError naming the path. `report_path`, when given, is the name the
// report gives the file: a file written beside its name and renamed into place is reported
// under the name it ends up with.
ConversionReport write_output(const ImageRGB& image, const std::string& out_path,
                              const OutputOptions& options, std::ostream& report_out,
                              const std::string& report_path = {});

}  // namespace tessera::color

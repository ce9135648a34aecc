// SPDX-License-Identifier: Apache-2.0
#include "output_flags.h"

#include "image/exr_io.h"

namespace tessera::cli {

void add_output_options(CLI::App& cmd, color::OutputOptions& o) {
  cmd.add_option("--tonemap", o.tonemap,
                 "Tone mapping for 8-bit/565/palette outputs (HDR outputs stay linear)")
      ->check(CLI::IsMember({"clamp", "reinhard", "aces", "pbr-neutral"}))
      ->capture_default_str();
  cmd.add_option("--exposure", o.exposure_ev, "Exposure in stops (EV), applied first")
      ->capture_default_str();
  cmd.add_option("--white", o.white,
                 "Reinhard white point after exposure (default: the brightest pixel)");
  cmd.add_option("--format", o.format, "Output format (default: from the file extension)")
      ->check(CLI::IsMember({"rgba8", "rgb8", "rgb565", "palette", "rgbe", "rgb9e5", "exr-half",
                             "exr-float"}));
  cmd.add_option("--colors", o.colors, "Palette size, 2..256 (implies --format palette for .png)")
      ->check(CLI::Range(2, 256));
  cmd.add_option("--dither", o.dither,
                 "bayer|blue-noise for rgb8/rgba8/rgb565, floyd-steinberg for palette")
      ->check(CLI::IsMember({"none", "bayer", "blue-noise", "floyd-steinberg"}))
      ->capture_default_str();
  cmd.add_option("--exr-compression", o.exr_compression,
                 "Lossless compression of EXR outputs: zip (the default), piz (smallest files), zips, rle, "
                 "none (fastest to write, largest)")
      ->check(CLI::IsMember(exr_compression_names()))
      ->capture_default_str();
  cmd.add_option("--report", o.report, "Report style")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str();
}

}  // namespace tessera::cli

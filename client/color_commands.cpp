// SPDX-License-Identifier: Apache-2.0
// `tessera convert` (HDR frame -> classic formats, with the error report) and
// `tessera palette-fade` (palette animation on an indexed PNG).
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "color/color_error.h"
#include "color/output_options.h"
#include "color/palette_fade.h"
#include "color/rgbe.h"
#include "commands.h"
#include "image/exr_io.h"
#include "interrupt.h"
#include "output_flags.h"

namespace tessera::cli {

namespace {

// EXR (any renderer's output) or Radiance .hdr.
ImageRGB read_hdr_input(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".hdr" || ext == ".rgbe" || ext == ".pic") {
    int w = 0, h = 0;
    const auto pixels = color::read_radiance_hdr(path, &w, &h);
    ImageRGB img(w, h);
    for (size_t p = 0; p < pixels.size(); ++p) {
      const color::Rgb c = color::decode_rgbe(pixels[p]);
      img.rgb[3 * p] = c.r;
      img.rgb[3 * p + 1] = c.g;
      img.rgb[3 * p + 2] = c.b;
    }
    return img;
  }
  return read_exr(path);
}

}  // namespace

void register_color_commands(CLI::App& app) {
  struct ConvertArgs {
    std::string input, output;
    color::OutputOptions out;
  };
  auto convert_args = std::make_shared<ConvertArgs>();
  CLI::App* convert = app.add_subcommand(
      "convert",
      "Tone map / quantize an EXR (or .hdr) to rgba8|rgb8 PNG, rgb565 BMP, palette PNG, RGBE .hdr, "
      "RGB9E5 .dds, half or float EXR, and report the error");
  convert->add_option("input", convert_args->input, "Input EXR or Radiance .hdr")
      ->required()
      ->check(CLI::ExistingFile);
  convert->add_option("output", convert_args->output, "Output file")->required();
  add_output_options(*convert, convert_args->out);
  convert->callback([convert_args] {
    const ImageRGB image = read_hdr_input(convert_args->input);
    const OutputWrite whole;  // an interrupt now waits for the file to be written
    color::write_output(image, convert_args->output, convert_args->out, std::cout);
  });

  struct FadeArgs {
    std::string input, pattern;
    int frames = 0;
  };
  auto fade_args = std::make_shared<FadeArgs>();
  CLI::App* fade = app.add_subcommand(
      "palette-fade",
      "Fade an indexed PNG to black by changing only its palette (indices stay byte-identical)");
  fade->add_option("input", fade_args->input, "Indexed (palette) PNG")
      ->required()
      ->check(CLI::ExistingFile);
  fade->add_option("--frames", fade_args->frames, "Number of frames, first = input, last = black")
      ->required()
      ->check(CLI::Range(2, 100000));
  fade->add_option("output", fade_args->pattern,
                   "Output pattern; the run of '#' becomes the frame number (1-based)")
      ->required();
  fade->callback([fade_args] {
    const auto written =
        color::write_palette_fade(fade_args->input, fade_args->frames, fade_args->pattern);
    std::cout << "palette-fade: " << written.size() << " frames, " << written.front() << " .. "
              << written.back() << " (PLTE changed, indices unchanged)\n";
  });
}

}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
// `tessera render SCENE -o OUT.exr`: the in-process renderer, no network. The farm's workers run
// exactly this code per tile, and this is the baseline the farm is measured against.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "color/output_options.h"
#include "command_error.h"
#include "commands.h"
#include "image_options.h"
#include "interrupt.h"
#include "image/exr_io.h"
#include "image/output_path.h"
#include "output_flags.h"
#include "render/embree_device.h"
#include "render/tile_renderer.h"
#include "sample_report.h"
#include "scene/scene_parser.h"

namespace tessera::cli {

namespace {

struct RenderArgs {
  std::string scene;
  std::string output;
  ImageOptions image;
  int frame = 0;
  int threads = 0;
  int tile = 32;
  bool quiet = false;
  bool error_channels = false;  // error.Y and spp.Y layers in the EXR
  color::OutputOptions color;  // tone mapping / format when -o is not a float EXR
};

// The farm confines a scene to its bundle (files under the scene's folder); locally nothing is
// refused, but a scene that reads elsewhere (an absolute or ../ mtllib, say) is not portable.
void warn_outside_bundle(const std::string& scene_path, const Scene& scene) {
  for (const std::string& dep : scene.dependencies) {
    const std::filesystem::path p = std::filesystem::path(dep).lexically_normal();
    if (p.is_absolute() || (!p.empty() && *p.begin() == "..")) {
      spdlog::warn("{}: reads '{}', outside the scene's folder: `tessera submit` cannot bundle it", scene_path, dep);
    }
  }
}

// The EXR header of a float EXR output: how it was rendered and its error estimate.
ExrAttributes render_attributes(const RenderArgs& a, const Scene& scene, const RenderOptions& options,
                                const FrameResult& r, const SampleSummary& samples) {
  ExrAttributes attrs{{"renderer", std::string("tessera 0.1.0 (") + embree_isa() + ")"},
                      {"tessera:scene", std::filesystem::path(a.scene).filename().string()},
                      {"tessera:frame", int64_t(a.frame)},
                      {"tessera:maxDepth", int64_t(scene.image.max_depth)},
                      {"tessera:rouletteWeight", scene.image.roulette_weight},
                      {"tessera:sampler", std::string(sampler_name(scene.image.sampler))},
                      {"tessera:triangleTest", std::string(triangle_test_name(options.triangles))},
                      {"tessera:seed", std::to_string(scene.image.seed)},
                      {"tessera:renderSeconds", r.seconds},
                      {"tessera:raysTraced", std::to_string(r.rays.total())}};
  if (!scene.image.adaptive()) attrs["tessera:spp"] = int64_t(scene.image.spp);
  add_sample_attributes(samples, scene.image, &attrs);
  return attrs;
}

// `conversion`: the tone mapping's JSON report when the output was converted, else empty.
void print_json_report(const RenderArgs& a, const std::string& out, const Scene& scene, const FrameResult& r,
                       const SampleSummary& samples, double build_s, double mrays, const std::string& conversion) {
  nlohmann::json j{{"output", out},
                   {"scene", a.scene},
                   {"frame", a.frame},
                   {"width", scene.image.width},
                   {"height", scene.image.height},
                   {"sampler", sampler_name(scene.image.sampler)},
                   {"seconds", r.seconds},
                   {"build_seconds", build_s},
                   {"mrays_per_s", mrays},
                   {"rays", {{"camera", r.rays.camera}, {"shadow", r.rays.shadow}, {"secondary", r.rays.secondary},
                             {"nonfinite_samples", r.rays.nonfinite_samples}}},
                   {"renderer", embree_isa()}};
  if (!scene.image.adaptive()) j["spp"] = scene.image.spp;
  j.update(samples_json(samples, scene.image));
  if (!conversion.empty()) j["conversion"] = nlohmann::json::parse(conversion);
  std::printf("%s\n", j.dump(2).c_str());
}

int run_render(const RenderArgs& a) {
  Scene scene;
  try {
    scene = load_scene_with(a.scene, a.image);
  } catch (const SceneError& e) {
    throw CommandError{kExitBadInput, e.what()};
  }
  warn_outside_bundle(a.scene, scene);
  if (a.frame < 0 || a.frame >= scene.frame_count()) {
    throw CommandError{kExitBadInput, "--frame: must be in [0, " + std::to_string(scene.frame_count() - 1) +
                                          "], got " + std::to_string(a.frame)};
  }
  const std::string out = frame_output_path(a.output, a.frame);
  const auto parent = std::filesystem::path(out).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);

  const auto t0 = std::chrono::steady_clock::now();
  const RenderOptions options;  // the defaults, as on every farm worker
  const std::shared_ptr<const RenderScene> rs = make_render_scene(scene, a.frame, options);
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool tty = !a.quiet && isatty(fileno(stderr));
  const FrameResult r = render_frame(*rs, a.tile, a.threads, [&](int done, int total) {
    if (tty && (done % 16 == 0 || done == total)) {
      std::fprintf(stderr, "\r  %d/%d tiles (%.0f%%)", done, total, 100.0 * done / total);
      if (done == total) std::fprintf(stderr, "\n");
    }
  });
  const double mrays = double(r.rays.total()) / r.seconds / 1e6;
  const SampleSummary samples = r.summary();
  const ExrAttributes attrs = render_attributes(a, scene, options, r, samples);
  const bool float_exr = color::is_float_exr_output(a.color, out);
  std::ostringstream conversion;
  if (a.error_channels && !float_exr) {
    throw CommandError{kExitBadInput, "--error-channels needs a float EXR output (-o ending in .exr, no --format)"};
  }
  set_exr_threads(a.threads);  // the EXR's compression runs on as many threads as the render
  try {
    const OutputWrite whole;  // an interrupt now waits for the file to be written
    if (float_exr) {
      const ErrorChannels channels =
          a.error_channels ? make_error_channels(r.variance, r.spp) : ErrorChannels{};
      // Keeps the render's attributes; the error layers on request.
      write_exr(out, r.image, attrs, ExrPixelType::kFloat,
                a.error_channels ? channels.channels() : std::vector<ExrChannel>{},
                parse_exr_compression(a.color.exr_compression));
    } else {
      // Tone map + quantize + its report: a line before the render's own, or a member of the JSON.
      color::write_output(r.image, out, a.color, a.color.report == "json" ? conversion : std::cout);
    }
  } catch (const std::exception& e) {
    throw CommandError{kExitFailure, e.what()};
  }
  if (r.rays.nonfinite_samples > 0) {
    spdlog::warn("{} samples had non-finite radiance and were replaced by 0", r.rays.nonfinite_samples);
  }
  if (const std::string w = target_warning(samples, scene.image); !w.empty()) spdlog::warn("{}", w);
  // --report json (shared with the color options): the whole result as one JSON object.
  if (a.color.report == "json") {
    print_json_report(a, out, scene, r, samples, build_s, mrays, conversion.str());
    return 0;
  }
  const std::string spp = scene.image.adaptive() ? "adaptive" : std::to_string(scene.image.spp) + " spp";
  std::printf("%s: %dx%d, %s, frame %d: %.3f s (+%.3f s scene build), %.2f Mrays/s "
              "(%llu camera, %llu shadow, %llu secondary), %s\n",
              out.c_str(), scene.image.width, scene.image.height, spp.c_str(), a.frame, r.seconds, build_s, mrays,
              (unsigned long long)r.rays.camera, (unsigned long long)r.rays.shadow,
              (unsigned long long)r.rays.secondary, describe_samples(samples, scene.image).c_str());
  return 0;
}

}  // namespace

void register_render_command(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "Render a scene in-process to a float OpenEXR file");
  cmd->add_option("scene", args->scene, "Scene file: JSON, or glTF 2.0 (.gltf/.glb); see docs/scene-format.md")->required();
  cmd->add_option("-o,--output", args->output, "Output EXR path; '#' runs become the frame number")->required();
  add_image_options(*cmd, args->image);
  cmd->add_option("--frame", args->frame, "Frame number to render (default 0)");
  cmd->add_option("--threads", args->threads, "Render threads, and the EXR's compression threads (default: all cores)")
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--tile", args->tile, "Tile size in pixels (does not change the image)")->check(CLI::Range(1, 4096));
  cmd->add_flag("-q,--quiet", args->quiet, "No progress display");
  cmd->add_flag("--error-channels", args->error_channels,
                "Add per-pixel layers to the EXR: error.Y (estimated RMSE of the pixel) and spp.Y (its samples)");
  // -o with another extension (or --format) writes that format directly: see `tessera convert`.
  add_output_options(*cmd, args->color);
  cmd->callback([args] { guarded("render", [&] { return run_render(*args); }); });
}

}  // namespace tessera::cli

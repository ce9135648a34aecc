// SPDX-License-Identifier: Apache-2.0
// POV-Ray as a peer (docs/performance.md, "A peer: POV-Ray 3.7"): compares POV-Ray's render of
// bench/povray/whitted.pov (rendered by bench/run_all.sh, linear EXR) with Tessera's render of
// scenes/whitted.json at the same size, in this process: RMSE in linear light of each against a
// high-spp Tessera reference, of the two against each other, and samples per second (wall and CPU)
// of each. Then the lowest spp at which Tessera's error is at most POV-Ray's, and the speed-up at
// that equal error. Prints JSON on stdout; appends markdown to --markdown. Asserts nothing about
// time.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <algorithm>
#include <map>
#include <vector>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "../bench_host.h"
#include "../bench_image.h"
#include "image/exr_io.h"
#include "render/embree_device.h"
#include "render/render_scene_internal.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"

namespace fs = std::filesystem;
using namespace tessera;

namespace {

using bench::rmse;

struct Run {
  int spp = 0;
  double mean_spp = 0;
  double wall = 0, cpu = 0, rmse = 0, estimated_rmse = 0;
  double camera_rays = 0;  // camera rays a pixel (lattice corners and audits included)
  LatticeCost lattice;     // a lattice render's rays and seconds by stage
  ImageRGB image;
};

// Renders `reps` times and keeps the fastest (CPU): a render here takes a tenth of a second, and
// the first one also pays for starting the thread pool.
Run render(const Scene& base, const RenderOptions& options, int spp, int threads, const ImageRGB& ref,
           double target_rmse = 0, int min_spp = 16, int reps = 3, SamplerKind sampler = SamplerKind::kSobol,
           uint64_t seed_offset = 0) {
  Scene s = base;
  s.image.spp = spp;
  s.image.target_rmse = target_rmse;
  s.image.min_spp = min_spp;
  s.image.sampler = sampler;
  s.image.seed += seed_offset;
  RenderScene rs(s, 0, options);
  Run run;
  run.cpu = run.wall = 1e30;
  for (int i = 0; i < reps; ++i) {
    const double c0 = bench::process_cpu_seconds();
    FrameResult r = render_frame(rs, 32, threads);
    const double cpu = bench::process_cpu_seconds() - c0;
    if (cpu >= run.cpu) continue;
    run.cpu = cpu;
    run.wall = r.seconds;
    run.rmse = rmse(r.image, ref);
    run.mean_spp = r.summary().mean_spp;
    run.estimated_rmse = r.summary().estimated_rmse;
    run.camera_rays = double(r.rays.camera) / (double(s.image.width) * double(s.image.height));
    run.lattice = r.lattice;
    run.image = std::move(r.image);
  }
  run.spp = spp;
  return run;
}

// Where the lattice render's rays and time went, and what that bounds: POV-Ray's CPU time over
// the CPU share of the corners alone (no refinement, no audits, no edge pixels at all), and of the
// pilot (corners, classification and audits) without the edge pixels' passes. Stages are wall
// time on all threads, so each stage's CPU time is taken as its share of the render's wall time.
nlohmann::json lattice_breakdown(const Run& lat, double pixels, double pov_cpu) {
  const LatticeCost& c = lat.lattice;
  const double staged = c.corner_seconds + c.classify_seconds + c.audit_seconds + c.pass_seconds;
  const double cpu_per_wall = lat.wall > 0 ? lat.cpu / lat.wall : 0;
  return {{"camera_rays_per_pixel", {{"corners", double(c.corner_rays) / pixels},
                                     {"audits", double(c.audit_rays) / pixels},
                                     {"edges", double(c.edge_rays) / pixels}}},
          {"pixels", {{"smooth", c.smooth_pixels}, {"audited", c.audited_pixels}, {"edge", c.edge_pixels}}},
          {"wall_s", {{"corners", c.corner_seconds}, {"classify", c.classify_seconds}, {"audits", c.audit_seconds},
                      {"passes", c.pass_seconds}, {"other", lat.wall - staged}}},
          {"passes", c.passes},
          {"bound_corners_only_cpu", pov_cpu / (c.corner_seconds * cpu_per_wall)},
          {"bound_pilot_only_cpu",
           pov_cpu / ((c.corner_seconds + c.classify_seconds + c.audit_seconds) * cpu_per_wall)}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Tessera against POV-Ray 3.7 on the Whitted showcase"};
  std::string scene_path, pov_exr, ref_path, markdown;
  int width = 320, height = 180, threads = 0, pov_spp = 16, max_spp = 1024;
  double pov_wall = 0, pov_cpu = 0;
  long long pov_samples = 0, pov_pixels = 0;
  app.add_option("--scene", scene_path)->required()->check(CLI::ExistingFile);
  app.add_option("--pov-exr", pov_exr, "POV-Ray's linear EXR output")->required()->check(CLI::ExistingFile);
  app.add_option("--pov-wall", pov_wall, "POV-Ray trace time, wall seconds (its log)")->required();
  app.add_option("--pov-cpu", pov_cpu, "POV-Ray trace CPU-seconds (its log)")->required();
  app.add_option("--pov-samples", pov_samples, "Samples POV-Ray reported (its anti-aliasing rays)")->required();
  app.add_option("--pov-pixels", pov_pixels, "Pixels POV-Ray reported (its first camera ray of each pixel)")->required();
  app.add_option("--pov-spp", pov_spp, "POV-Ray's samples per pixel (+R n: n*n)");
  app.add_option("--reference", ref_path, "High-spp Tessera reference EXR (bench/speed_error's cache)")
      ->required()->check(CLI::ExistingFile);
  app.add_option("--width", width);
  app.add_option("--height", height);
  app.add_option("--threads", threads, "Tessera threads (give POV-Ray the same +WT)");
  app.add_option("--max-spp", max_spp, "Give up the equal-error search here");
  app.add_option("--markdown", markdown);
  std::string pov_settings = "+A0.0 +AM1";
  app.add_option("--pov-settings", pov_settings, "POV-Ray's anti-aliasing flags, for the tables");
  int target_min_spp = 2;  // --target-rmse's own default: its pilot
  app.add_option("--target-min-spp", target_min_spp, "--min-spp of the target-error renders")->check(CLI::Range(2, 1024));
  RenderOptions options;
  const std::map<std::string, SphereSearch> sphere_searches = {
      {sphere_search_name(SphereSearch::kScanSmall), SphereSearch::kScanSmall},
      {sphere_search_name(SphereSearch::kEmbree), SphereSearch::kEmbree}};
  app.add_option("--spheres", options.spheres, "How Tessera finds the spheres (render/render_options.h)")
      ->transform(CLI::CheckedTransformer(sphere_searches));
  bool lattice = true;
  app.add_option("--lattice", lattice, "Also the target-error search with --sampler lattice (render/lattice_sampler.h)");
  int honesty_seeds = 0;
  app.add_option("--honesty-seeds", honesty_seeds,
                 "Render each target-error result again with this many other seeds: estimated / measured RMSE");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  Scene scene = load_scene(scene_path);
  scene.image.width = width;
  scene.image.height = height;
  const ImageRGB ref = read_exr(ref_path);
  const ImageRGB pov = read_exr(pov_exr);
  if (ref.width != width || ref.height != height || pov.width != width || pov.height != height) {
    std::cerr << "pov_compare: image sizes differ: reference " << ref.width << "x" << ref.height << ", POV-Ray "
              << pov.width << "x" << pov.height << ", expected " << width << "x" << height << "\n";
    return 2;
  }
  const double pov_rmse = rmse(pov, ref);

  // Same samples per pixel as POV-Ray, then the equal-error search: powers of two up to the first
  // that reaches POV-Ray's error, then every count between it and the one below.
  const Run same = render(scene, options, pov_spp, threads, ref);
  Run equal;
  int low = 0;
  for (int spp = 1; spp <= max_spp; spp *= 2) {
    Run r = spp == pov_spp ? same : render(scene, options, spp, threads, ref);
    equal = std::move(r);
    if (equal.rmse <= pov_rmse) break;
    low = spp;
  }
  for (int spp = low + 1; equal.rmse <= pov_rmse && spp < equal.spp; ++spp) {
    Run r = render(scene, options, spp, threads, ref);
    if (r.rmse <= pov_rmse) {
      equal = std::move(r);
      break;
    }
  }
  // Target-error rendering (--target-rmse, the frame's error; --min-spp --target-min-spp): the
  // loosest target, from 1.3x POV-Ray's error down in steps of 5%, whose render reaches POV-Ray's
  // error. (The frame's estimate lands at 0.9-1.0x of its target and is honest to within 0.8-1.25x,
  // so the search starts a little above POV-Ray's error.)
  Run target;
  double target_rmse = 1.3 * pov_rmse;
  for (int i = 0; i < 40; ++i, target_rmse *= 0.95) {
    target = render(scene, options, 1, threads, ref, target_rmse, target_min_spp);
    if (target.rmse <= pov_rmse) break;
  }
  const bool target_reached = target.rmse <= pov_rmse;
  // The same search with the lattice sampler.
  Run lat;
  double lattice_target = 1.3 * pov_rmse;
  for (int i = 0; lattice && i < 40; ++i, lattice_target *= 0.95) {
    lat = render(scene, options, 1, threads, ref, lattice_target, target_min_spp, 3, SamplerKind::kLattice);
    if (lat.rmse <= pov_rmse) break;
  }
  const bool lattice_reached = lattice && lat.rmse <= pov_rmse;
  // How honest each result's estimate is over other seeds: estimated / measured RMSE.
  auto honesty = [&](double t, SamplerKind k) {
    std::vector<double> ratios;
    for (int seed = 1; seed <= honesty_seeds; ++seed) {
      const Run r = render(scene, options, 1, threads, ref, t, target_min_spp, 1, k, uint64_t(seed));
      ratios.push_back(r.estimated_rmse / r.rmse);
    }
    std::sort(ratios.begin(), ratios.end());
    return ratios;
  };
  const std::vector<double> target_honesty = honesty(target_rmse, SamplerKind::kSobol);
  const std::vector<double> lattice_honesty = lattice ? honesty(lattice_target, SamplerKind::kLattice)
                                                      : std::vector<double>{};
  auto spread = [](const std::vector<double>& r) {
    char buf[128] = "";
    if (!r.empty()) std::snprintf(buf, sizeof buf, "%.2f / %.2f / %.2f", r.front(), r[r.size() / 2], r.back());
    return std::string(buf);
  };
  const double px = double(width) * double(height);
  const double t_sps_wall = px * same.spp / same.wall, t_sps_cpu = px * same.spp / same.cpu;
  // POV-Ray's camera rays are its "Pixels" and its "Samples" together: a render without
  // anti-aliasing reports Pixels = W*H and Samples 0, and in every log Rays = Pixels + Samples +
  // reflected + refracted rays. "Samples" alone counts only the anti-aliasing rays, which at +A0.3
  // made POV-Ray look like 0.87 rays a pixel where it traces 1.94.
  const double pov_rays = double(pov_pixels) + double(pov_samples);
  const double p_sps_wall = pov_rays / pov_wall, p_sps_cpu = pov_rays / pov_cpu;
  const bool reached = equal.rmse <= pov_rmse;
  nlohmann::json out = {
      {"scene", fs::path(scene_path).stem().string()},
      {"width", width},
      {"height", height},
      {"threads", threads},
      {"renderer", embree_isa()},
      {"spheres", sphere_search_name(options.spheres)},
      {"povray", {{"samples", pov_samples}, {"pixels", pov_pixels}, {"camera_rays", pov_rays}, {"spp", pov_spp},
                  {"settings", pov_settings}, {"camera_rays_per_pixel", pov_rays / px}, {"wall_s", pov_wall}, {"cpu_s", pov_cpu},
                  {"samples_per_s_wall", p_sps_wall}, {"samples_per_s_cpu", p_sps_cpu}, {"rmse_vs_reference", pov_rmse}}},
      {"tessera_same_spp", {{"spp", same.spp}, {"wall_s", same.wall}, {"cpu_s", same.cpu},
                            {"samples_per_s_wall", t_sps_wall}, {"samples_per_s_cpu", t_sps_cpu},
                            {"rmse_vs_reference", same.rmse}}},
      {"rmse_povray_vs_tessera_same_spp", rmse(pov, same.image)},
      {"throughput_ratio_wall", t_sps_wall / p_sps_wall},
      {"throughput_ratio_cpu", t_sps_cpu / p_sps_cpu},
      {"equal_error", {{"reached", reached}, {"spp", equal.spp}, {"wall_s", equal.wall}, {"cpu_s", equal.cpu},
                       {"rmse", equal.rmse}, {"speedup_wall", pov_wall / equal.wall}, {"speedup_cpu", pov_cpu / equal.cpu}}},
      {"target_error", {{"reached", target_reached}, {"target_rmse", target_rmse}, {"mean_spp", target.mean_spp},
                        {"wall_s", target.wall}, {"cpu_s", target.cpu}, {"rmse", target.rmse},
                        {"speedup_wall", pov_wall / target.wall}, {"speedup_cpu", pov_cpu / target.cpu},
                        {"camera_rays_per_pixel", target.camera_rays}, {"estimated_rmse", target.estimated_rmse},
                        {"honesty", target_honesty}}}};
  if (lattice) {
    out["lattice_target_error"] = {{"reached", lattice_reached}, {"target_rmse", lattice_target},
                                   {"mean_spp", lat.mean_spp}, {"camera_rays_per_pixel", lat.camera_rays},
                                   {"wall_s", lat.wall}, {"cpu_s", lat.cpu}, {"rmse", lat.rmse},
                                   {"estimated_rmse", lat.estimated_rmse}, {"speedup_wall", pov_wall / lat.wall},
                                   {"speedup_cpu", pov_cpu / lat.cpu}, {"honesty", lattice_honesty},
                                   {"breakdown", lattice_breakdown(lat, px, pov_cpu)}};
  }
  std::cout << out.dump(2) << "\n";
  if (!markdown.empty()) {
    std::ofstream md(markdown, std::ios::app);
    char buf[1024];
    md << "| | spp | wall s | CPU s | samples/s (wall) | samples/s (CPU) | RMSE vs reference |\n|---|---:|---:|---:|---:|---:|---:|\n";
    std::snprintf(buf, sizeof buf, "| POV-Ray 3.7 `%s` | %.2f (camera rays a pixel) | %.3f | %.3f | %.3g | %.3g | %.4g |\n",
                  pov_settings.c_str(), pov_rays / px, pov_wall, pov_cpu, p_sps_wall, p_sps_cpu, pov_rmse);
    md << buf;
    std::snprintf(buf, sizeof buf, "| Tessera, same spp | %d | %.3f | %.3f | %.3g | %.3g | %.4g |\n", same.spp, same.wall,
                  same.cpu, t_sps_wall, t_sps_cpu, same.rmse);
    md << buf;
    std::snprintf(buf, sizeof buf, "| Tessera, equal error | %d | %.3f | %.3f | | | %.4g |\n", equal.spp, equal.wall,
                  equal.cpu, equal.rmse);
    md << buf;
    std::snprintf(buf, sizeof buf, "| Tessera, --target-rmse %.3g --min-spp %d | %.1f (mean) | %.3f | %.3f | | | %.4g |\n",
                  target_rmse, target_min_spp, target.mean_spp, target.wall, target.cpu, target.rmse);
    md << buf;
    if (lattice) {
      std::snprintf(buf, sizeof buf,
                    "| Tessera, --sampler lattice --target-rmse %.3g | %.2f (camera rays a pixel) | %.3f | %.3f | | | %.4g |\n",
                    lattice_target, lat.camera_rays, lat.wall, lat.cpu, lat.rmse);
      md << buf;
    }
    const double best_cpu = std::max(pov_cpu / equal.cpu, target_reached ? pov_cpu / target.cpu : 0.0);
    std::snprintf(buf, sizeof buf,
                  "\nRMSE between the two images at %d spp: %.4g. Throughput (samples/s) Tessera / POV-Ray: %.2fx wall, "
                  "%.2fx CPU. At equal or lower error (%s at %d spp): %.2fx faster (wall), %.2fx (CPU); with "
                  "--target-rmse (%s): %.2fx (wall), %.2fx (CPU). Goal 5x (CPU, on the way to 10x): %s.\n",
                  pov_spp, rmse(pov, same.image), t_sps_wall / p_sps_wall, t_sps_cpu / p_sps_cpu,
                  reached ? "reached" : "NOT reached", equal.spp, pov_wall / equal.wall, pov_cpu / equal.cpu,
                  target_reached ? "reached" : "NOT reached", pov_wall / target.wall, pov_cpu / target.cpu,
                  (reached || target_reached) && best_cpu >= 5 ? "met" : "not met");
    md << buf;
    if (lattice) {
      std::snprintf(buf, sizeof buf,
                    "With --sampler lattice (%s): %.2fx (wall), %.2fx (CPU), estimated RMSE %.4g against %.4g measured.",
                    lattice_reached ? "reached" : "NOT reached", pov_wall / lat.wall, pov_cpu / lat.cpu,
                    lat.estimated_rmse, lat.rmse);
      md << buf;
      const nlohmann::json b = lattice_breakdown(lat, px, pov_cpu);
      const auto& r = b["camera_rays_per_pixel"];
      const auto& w = b["wall_s"];
      std::snprintf(buf, sizeof buf,
                    " Its camera rays a pixel: corners %.2f, audits %.2f, edge pixels %.2f (%lld of %lld pixels, %d "
                    "passes); its wall time: corners %.1f ms, classification %.1f ms, audits %.1f ms, passes %.1f ms; "
                    "POV-Ray's CPU time over the corners' alone %.1fx, over the pilot's %.1fx.",
                    r["corners"].get<double>(), r["audits"].get<double>(), r["edges"].get<double>(),
                    (long long)lat.lattice.edge_pixels, (long long)px, lat.lattice.passes,
                    1e3 * w["corners"].get<double>(), 1e3 * w["classify"].get<double>(), 1e3 * w["audits"].get<double>(),
                    1e3 * w["passes"].get<double>(), b["bound_corners_only_cpu"].get<double>(),
                    b["bound_pilot_only_cpu"].get<double>());
      md << buf;
    }
    if (honesty_seeds > 0) {
      md << " Estimated / measured RMSE over " << honesty_seeds << " other seeds (min / median / max): target "
         << spread(target_honesty) << (lattice ? ", lattice " + spread(lattice_honesty) : std::string()) << ".";
    }
    md << "\n";
  }
  return 0;
}

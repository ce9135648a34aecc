// SPDX-License-Identifier: Apache-2.0
// How honest the lattice sampler's error estimate is on hard scenes (bench/lattice/scenes:
// sub-pixel spheres, wires, thin shadows, small objects seen only in a mirror or through glass,
// hard spot-light cones, total internal reflection, a checker to the horizon; docs/accuracy.md,
// "The lattice sampler's error estimate").
//
// For each scene: a sobol reference at --ref-spp (cached as EXR in --cache, keyed by scene name,
// size and spp; a hash of the scene file and its meshes, stored in the EXR, re-renders it when
// they change), then for each target error T (by default the measured RMSE of uniform sobol
// renders at 4, 16 and 64 spp, rendered here) renders --target-rmse T with --sampler lattice and
// with the default sobol frame target for seeds 1..--seeds, and reports per scene, target and
// sampler the honesty ratios (the frame's estimated RMSE over the RMSE measured against the
// reference) sorted, their min / median / max, camera rays a pixel, measured RMSE and CPU
// seconds (of render_frame alone); for the lattice also the smooth pixels' share of both errors
// and, per seed, where the smooth pixels' error is and how much of it their audits saw. Prints
// JSON on stdout; appends a markdown table to --markdown; --error-dir writes |lattice -
// reference| images. Asserts nothing about time.
//
//   lattice_honesty --scene bench/lattice/scenes/wires.json [--scene ...] [--ref-spp 1024]
//                   [--seeds 8] [--targets auto|0.01,0.005] [--target-spp 4,16,64]
//                   [--cache DIR] [--markdown OUT.md] [--width W --height H] [--threads N]
//                   [--error-dir DIR]
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>
#include <xxhash.h>

#include "../bench_host.h"
#include "../bench_image.h"
#include "image/exr_io.h"
#include "render/embree_device.h"
#include "render/lattice_sampler.h"
#include "render/render_scene_internal.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"

namespace fs = std::filesystem;
using namespace tessera;

namespace {

struct Options {
  std::vector<std::string> scenes;
  int width = 0, height = 0;  // 0: the scene's own
  int ref_spp = 1024, seeds = 8, threads = 0, min_spp = 0;
  std::string cache = "bench-cache", markdown, targets = "auto", target_spp = "4,16,64", error_dir;
};

// One render measured against the reference. A lattice render's smooth pixels (its pilot's) and
// edge pixels split both errors: smooth_* + edge_* = the frame's mean squared error (all of it
// edge_* for sobol).
struct Run {
  double rmse = 0, estimated_rmse = 0, camera_rays = 0, cpu = 0, mean_spp = 0;
  bool reached = true;
  double smooth_fraction = 0, audited_fraction = 0;
  double smooth_mse = 0, smooth_est_mse = 0, edge_mse = 0, edge_est_mse = 0;
  // Where the smooth pixels' error is: the fewest of them holding 90% of their squared error, how
  // many of those were audited, and their estimate over their squared error (the audits' expected
  // value: 1); the largest audit's share of the smooth pixels' estimate.
  int64_t smooth_pixels_90 = 0, audited_90 = 0;
  double estimated_share_90 = 0, top_audit_share = 0;
  std::vector<std::array<double, 3>> worst_smooth;  // the 5 smooth pixels of largest error: x, y, RMSE
  LatticeCost lattice;                              // the lattice's smooth, audited and edge pixels
  double ratio() const { return rmse > 0 ? estimated_rmse / rmse : 0.0; }
};

struct Reference {
  ImageRGB image;
  std::string path;
  double estimated_rmse = 0, cpu = 0;
  bool cached = false;
};

// XXH3-64 of the scene file and every file it names (meshes, their materials), in that order.
std::string scene_hash(const Scene& scene) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  XXH3_64bits_reset(state.get());
  auto add = [&](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    char buf[1 << 16];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) XXH3_64bits_update(state.get(), buf, size_t(in.gcount()));
  };
  add(scene.path);
  const fs::path dir = fs::path(scene.path).parent_path();
  for (const std::string& dep : scene.dependencies) add(dir / dep);
  char out[20];
  std::snprintf(out, sizeof out, "%016llx", static_cast<unsigned long long>(XXH3_64bits_digest(state.get())));
  return out;
}

using bench::rmse;

double median(const std::vector<double>& sorted) {
  if (sorted.empty()) return 0;
  const size_t n = sorted.size();
  return n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
}

// The sobol reference at o.ref_spp, seed + 1000 (its noise independent of the renders measured
// against it), read from the cache when there with the same scene hash.
Reference reference(const Scene& scene, const std::string& name, const Options& o) {
  Reference ref;
  const int w = scene.image.width, h = scene.image.height;
  ref.path = o.cache + "/" + name + "_" + std::to_string(w) + "x" + std::to_string(h) + "_ref" +
             std::to_string(o.ref_spp) + "_sobol.exr";
  const std::string hash = scene_hash(scene);
  if (fs::exists(ref.path)) {
    ExrAttributes attrs;
    ImageRGB img = read_exr(ref.path, &attrs);
    const auto it = attrs.find("tessera:sceneHash");
    const bool same = it != attrs.end() && std::holds_alternative<std::string>(it->second) &&
                      std::get<std::string>(it->second) == hash;
    if (same && img.width == w && img.height == h) {
      if (auto e = attrs.find("tessera:estimatedRmse"); e != attrs.end() && std::holds_alternative<double>(e->second)) {
        ref.estimated_rmse = std::get<double>(e->second);
      }
      ref.image = std::move(img);
      ref.cached = true;
      return ref;
    }
    std::cerr << "lattice_honesty: " << ref.path << " is of another version of the scene: rendering it again\n";
  }
  Scene s = scene;
  s.image.spp = o.ref_spp;
  s.image.sampler = SamplerKind::kSobol;
  s.image.target_rmse = 0;
  s.image.seed = scene.image.seed + 1000;
  RenderScene rs(s, 0);
  const double c0 = bench::process_cpu_seconds();
  FrameResult r = render_frame(rs, 32, o.threads);
  ref.cpu = bench::process_cpu_seconds() - c0;
  ref.estimated_rmse = r.estimated_rmse();
  ref.image = std::move(r.image);
  fs::create_directories(o.cache);
  write_exr(ref.path, ref.image,
            {{"tessera:spp", int64_t(o.ref_spp)},
             {"tessera:estimatedRmse", ref.estimated_rmse},
             {"tessera:renderSeconds", r.seconds},
             {"tessera:sceneHash", hash}});
  std::cerr << "lattice_honesty: reference " << ref.path << " rendered in " << ref.cpu << " CPU-s\n";
  return ref;
}

// Writes |image - ref| per channel, with spp.Y and error.Y (the estimated RMSE of each pixel) beside.
void write_error_image(const std::string& path, const FrameResult& r, const ImageRGB& ref) {
  ImageRGB diff = r.image;
  for (size_t i = 0; i < diff.rgb.size(); ++i) diff.rgb[i] = std::fabs(r.image.rgb[i] - ref.rgb[i]);
  std::vector<float> spp(r.spp.begin(), r.spp.end()), err(r.variance.size());
  for (size_t i = 0; i < err.size(); ++i) err[i] = std::sqrt(std::max(0.0f, r.variance[i]));
  write_exr(path, diff, {}, ExrPixelType::kFloat, {{"spp.Y", &spp}, {"error.Y", &err}});
}

// Splits the frame's measured and estimated squared errors between the smooth pixels (`smooth`:
// the lattice pilot's; all 0 for sobol) and the others, and finds where the smooth ones' is.
void split_errors(const FrameResult& r, const ImageRGB& ref, const std::vector<uint8_t>& smooth, Run* run) {
  const double pixels = double(r.spp.size());
  std::vector<std::pair<double, size_t>> smooth_err;  // (squared error, pixel)
  double top_audit = 0;
  for (size_t p = 0; p < r.spp.size(); ++p) {
    double e = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = double(r.image.rgb[3 * p + c]) - double(ref.rgb[3 * p + c]);
      e += d * d / 3;
    }
    const bool is_smooth = smooth[p] != 0;
    (is_smooth ? run->smooth_mse : run->edge_mse) += e / pixels;
    (is_smooth ? run->smooth_est_mse : run->edge_est_mse) += double(r.variance[p]) / pixels;
    if (!is_smooth) continue;
    run->smooth_fraction += 1 / pixels;
    run->audited_fraction += r.spp[p] == 3 ? 1 / pixels : 0;  // an audited smooth pixel: spp 3
    smooth_err.emplace_back(e, p);
    top_audit = std::max(top_audit, double(r.variance[p]));
  }
  std::sort(smooth_err.begin(), smooth_err.end(), std::greater<>());
  double held = 0, estimated = 0;
  while (size_t(run->smooth_pixels_90) < smooth_err.size() && held < 0.9 * run->smooth_mse * pixels) {
    const auto [e, p] = smooth_err[size_t(run->smooth_pixels_90++)];
    held += e;
    estimated += double(r.variance[p]);
    run->audited_90 += r.spp[p] == 3 ? 1 : 0;
  }
  run->estimated_share_90 = held > 0 ? estimated / held : 0.0;
  for (size_t i = 0; i < std::min<size_t>(5, smooth_err.size()); ++i) {
    const auto [e, p] = smooth_err[i];
    const size_t w = size_t(r.image.width);
    run->worst_smooth.push_back({double(p % w), double(p / w), std::sqrt(e)});
  }
  run->top_audit_share = run->smooth_est_mse > 0 ? top_audit / (run->smooth_est_mse * pixels) : 0.0;
}

// One render: a uniform one (target 0, `spp` samples) or to the frame target `target`.
Run render(const Scene& base, SamplerKind sampler, int spp, double target, uint64_t seed_offset, const Options& o,
           const ImageRGB& ref, const std::string& error_path = {}) {
  Scene s = base;
  s.image.sampler = sampler;
  s.image.spp = spp;
  s.image.target_rmse = target;
  s.image.min_spp = target > 0 ? o.min_spp : 0;
  s.image.seed = base.image.seed + seed_offset;
  RenderScene rs(s, 0);
  const double c0 = bench::process_cpu_seconds();
  const FrameResult r = render_frame(rs, 32, o.threads);
  Run run;
  run.cpu = bench::process_cpu_seconds() - c0;
  run.rmse = rmse(r.image, ref);
  const SampleSummary sum = r.summary();
  run.estimated_rmse = sum.estimated_rmse;
  run.mean_spp = sum.mean_spp;
  run.reached = sum.target_reached;
  run.camera_rays = double(r.rays.camera) / (double(s.image.width) * double(s.image.height));
  run.lattice = r.lattice;
  // Which pixels the lattice called smooth: its pilot again (a pure function of the scene and
  // settings, so the same pixels), untimed.
  std::vector<uint8_t> smooth(r.spp.size(), 0);
  if (sampler == SamplerKind::kLattice) {
    tbb::task_arena arena(o.threads > 0 ? o.threads : tbb::task_arena::automatic);
    arena.execute([&] { smooth = render_lattice_pilot(rs).smooth; });
  }
  split_errors(r, ref, smooth, &run);
  if (!error_path.empty()) write_error_image(error_path, r, ref);
  return run;
}

// Per sampler over the seeds: the ratios sorted with their spread, the means of the rest, each
// seed's errors (smooth and edge pixels apart for the lattice). The partial errors over the seeds
// are root mean squares. `ref_mse`: the reference's own estimated squared error, which every
// measured error holds too; "ref_corrected" takes it out of the measured one (a check on how much
// of a ratio under 1 is the reference's noise, not the estimate's).
nlohmann::json sampler_json(const std::vector<Run>& runs, bool lattice, double ref_mse) {
  std::vector<double> ratios, corrected;
  double rays = 0, cpu = 0, est = 0, rmse = 0, spp = 0, smooth = 0, audited = 0;
  double s_mse = 0, s_est = 0, e_mse = 0, e_est = 0;
  int reached = 0;
  const double n = double(runs.size());
  nlohmann::json seeds = nlohmann::json::array();
  for (size_t i = 0; i < runs.size(); ++i) {
    const Run& r = runs[i];
    ratios.push_back(r.ratio());
    corrected.push_back(r.estimated_rmse / std::sqrt(std::max(r.rmse * r.rmse - ref_mse, 1e-30)));
    rays += r.camera_rays / n;
    cpu += r.cpu / n;
    est += r.estimated_rmse / n;
    rmse += r.rmse / n;
    spp += r.mean_spp / n;
    smooth += r.smooth_fraction / n;
    audited += r.audited_fraction / n;
    s_mse += r.smooth_mse / n;
    s_est += r.smooth_est_mse / n;
    e_mse += r.edge_mse / n;
    e_est += r.edge_est_mse / n;
    reached += r.reached ? 1 : 0;
    nlohmann::json seed = {
        {"seed", i + 1}, {"ratio", r.ratio()}, {"rmse", r.rmse}, {"estimated_rmse", r.estimated_rmse}};
    if (lattice) {
      seed["smooth"] = {{"rmse", std::sqrt(r.smooth_mse)}, {"estimated_rmse", std::sqrt(r.smooth_est_mse)}};
      seed["edge"] = {{"rmse", std::sqrt(r.edge_mse)}, {"estimated_rmse", std::sqrt(r.edge_est_mse)}};
      seed["smooth_pixels_holding_90pct"] = r.smooth_pixels_90;
      seed["of_those_audited"] = r.audited_90;
      seed["of_those_estimate_over_error"] = r.estimated_share_90;
      seed["worst_smooth_pixels"] = r.worst_smooth;
      seed["top_audit_share"] = r.top_audit_share;
      seed["pixels"] = {
          {"smooth", r.lattice.smooth_pixels}, {"audited", r.lattice.audited_pixels}, {"edge", r.lattice.edge_pixels}};
    }
    seeds.push_back(std::move(seed));
  }
  std::sort(ratios.begin(), ratios.end());
  std::sort(corrected.begin(), corrected.end());
  const auto lo = [](const std::vector<double>& v) { return v.empty() ? 0.0 : v.front(); };
  const auto hi = [](const std::vector<double>& v) { return v.empty() ? 0.0 : v.back(); };
  nlohmann::json j = {
      {"honesty", ratios},
      {"min", lo(ratios)},
      {"median", median(ratios)},
      {"max", hi(ratios)},
      {"ref_corrected", {{"min", lo(corrected)}, {"median", median(corrected)}, {"max", hi(corrected)}}},
      {"camera_rays_per_pixel", rays},
      {"mean_spp", spp},
      {"rmse", rmse},
      {"estimated_rmse", est},
      {"cpu_s", cpu},
      {"targets_reached", reached},
      {"seeds", seeds}};
  if (lattice) {
    j["smooth_fraction"] = smooth;
    j["audited_fraction"] = audited;
    j["smooth_pixels"] = {{"rmse", std::sqrt(s_mse)}, {"estimated_rmse", std::sqrt(s_est)}};
    j["edge_pixels"] = {{"rmse", std::sqrt(e_mse)}, {"estimated_rmse", std::sqrt(e_est)}};
  }
  return j;
}

std::vector<double> parse_numbers(const std::string& list, const char* what) {
  std::vector<double> out;
  std::stringstream ss(list);
  for (std::string t; std::getline(ss, t, ',');) {
    size_t used = 0;
    double v = 0;
    try {
      v = std::stod(t, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != t.size() || !(v > 0))
      throw std::invalid_argument(std::string(what) + ": '" + t + "' is not a positive number");
    out.push_back(v);
  }
  return out;
}

// The targets: given, or the measured RMSE of uniform sobol renders (seed offset 0, unlike every
// measured render) at o.target_spp.
std::vector<std::pair<double, std::string>> targets(const Scene& scene, const Options& o, const ImageRGB& ref,
                                                    nlohmann::json* uniform) {
  std::vector<std::pair<double, std::string>> out;
  if (o.targets != "auto") {
    for (double t : parse_numbers(o.targets, "--targets")) out.emplace_back(t, "given");
    return out;
  }
  for (double spp : parse_numbers(o.target_spp, "--target-spp")) {
    const Run u = render(scene, SamplerKind::kSobol, int(spp), 0, 0, o, ref);
    uniform->push_back({{"spp", int(spp)}, {"rmse", u.rmse}, {"estimated_rmse", u.estimated_rmse}, {"cpu_s", u.cpu}});
    out.emplace_back(u.rmse, "sobol " + std::to_string(int(spp)) + " spp");
  }
  return out;
}

std::string spread(const nlohmann::json& j) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.2f / %.2f / %.2f", j["min"].get<double>(), j["median"].get<double>(),
                j["max"].get<double>());
  return buf;
}

// One scene: its reference, targets and renders; a JSON object and markdown rows.
nlohmann::json run_scene(const Scene& scene, const std::string& name, const Options& o, std::string* md_rows) {
  const Reference ref = reference(scene, name, o);
  nlohmann::json uniform = nlohmann::json::array();
  const auto ts = targets(scene, o, ref.image, &uniform);
  nlohmann::json out = {{"scene", name},
                        {"file", scene.path},
                        {"width", scene.image.width},
                        {"height", scene.image.height},
                        {"max_depth", scene.image.max_depth},
                        {"reference",
                         {{"path", ref.path},
                          {"spp", o.ref_spp},
                          {"estimated_rmse", ref.estimated_rmse},
                          {"cached", ref.cached},
                          {"cpu_s", ref.cpu}}},
                        {"uniform", uniform},
                        {"targets", nlohmann::json::array()}};
  const double ref_mse = ref.estimated_rmse * ref.estimated_rmse;
  for (size_t ti = 0; ti < ts.size(); ++ti) {
    const auto& [t, from] = ts[ti];
    std::vector<Run> lat, sob;
    for (int seed = 1; seed <= o.seeds; ++seed) {
      std::string err_path;
      if (!o.error_dir.empty() && seed == 1) {
        err_path = o.error_dir + "/" + name + "_t" + std::to_string(ti) + "_lattice_error.exr";
      }
      lat.push_back(render(scene, SamplerKind::kLattice, 1, t, uint64_t(seed), o, ref.image, err_path));
      sob.push_back(render(scene, SamplerKind::kSobol, 1, t, uint64_t(seed), o, ref.image));
    }
    nlohmann::json row = {{"target_rmse", t},
                          {"from", from},
                          {"lattice", sampler_json(lat, true, ref_mse)},
                          {"sobol", sampler_json(sob, false, ref_mse)}};
    std::cerr << "  " << name << " target " << t << " (" << from << "): lattice " << spread(row["lattice"])
              << ", sobol " << spread(row["sobol"]) << "\n";
    char buf[512];
    std::snprintf(buf, sizeof buf, "| %s | %.3g (%s) | %s | %s | %.2f | %.2f |\n", name.c_str(), t, from.c_str(),
                  spread(row["lattice"]).c_str(), spread(row["sobol"]).c_str(),
                  row["lattice"]["camera_rays_per_pixel"].get<double>(),
                  row["sobol"]["camera_rays_per_pixel"].get<double>());
    *md_rows += buf;
    out["targets"].push_back(std::move(row));
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"How honest the lattice sampler's error estimate is: estimated / measured RMSE on hard scenes"};
  Options o;
  app.add_option("--scene", o.scenes, "Scene JSON; repeatable, or a list (space- or comma-separated)")
      ->required()
      ->delimiter(',');
  app.add_option("--width", o.width, "Image width (default: the scene's)")->check(CLI::Range(1, 16384));
  app.add_option("--height", o.height, "Image height (default: the scene's)")->check(CLI::Range(1, 16384));
  app.add_option("--ref-spp", o.ref_spp, "Reference spp (sobol), cached in --cache")->check(CLI::Range(1, 65536));
  app.add_option("--seeds", o.seeds, "Renders per sampler and target, seeds 1..N")->check(CLI::Range(1, 256));
  app.add_option(
      "--targets", o.targets,
      "Target RMSEs, comma-separated, or 'auto': the measured RMSE of uniform sobol renders at --target-spp");
  app.add_option("--target-spp", o.target_spp, "With --targets auto: the uniform renders' spp, comma-separated");
  app.add_option("--min-spp", o.min_spp, "--min-spp of the target renders (0: the default, 2)")
      ->check(CLI::Range(0, 1024));
  app.add_option("--threads", o.threads, "Render threads (0 = all cores)")->check(CLI::Range(0, 4096));
  app.add_option("--cache", o.cache, "Directory for cached references");
  app.add_option("--markdown", o.markdown, "Append a markdown table to this file");
  app.add_option(
      "--error-dir", o.error_dir,
      "Write |lattice - reference| of seed 1 of each target here as EXR, with spp.Y (1: smooth) and error.Y");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  // Every scene loads before anything renders: a broken one fails the run at once.
  std::vector<std::pair<std::string, Scene>> scenes;
  for (const std::string& path : o.scenes) {
    try {
      Scene s = load_scene(path);
      if (o.width > 0) s.image.width = o.width;
      if (o.height > 0) s.image.height = o.height;
      scenes.emplace_back(fs::path(path).stem().string(), std::move(s));
    } catch (const std::exception& e) {
      std::cerr << "lattice_honesty: cannot load scene " << path << ": " << e.what() << "\n";
      return 2;
    }
  }
  if (!o.error_dir.empty()) fs::create_directories(o.error_dir);
  nlohmann::json out = {{"cpu", bench::cpu_model()},
                        {"renderer", embree_isa()},
                        {"threads", o.threads},
                        {"ref_spp", o.ref_spp},
                        {"seeds", o.seeds},
                        {"min_spp", o.min_spp},
                        {"scenes", nlohmann::json::array()}};
  std::string md_rows;
  const double c0 = bench::process_cpu_seconds();
  try {
    for (const auto& [name, scene] : scenes) out["scenes"].push_back(run_scene(scene, name, o, &md_rows));
  } catch (const std::exception& e) {
    std::cerr << "lattice_honesty: " << e.what() << "\n";
    return 2;
  }
  out["cpu_s"] = bench::process_cpu_seconds() - c0;
  std::cout << out.dump(2) << "\n";
  if (!o.markdown.empty()) {
    std::ofstream md(o.markdown, std::ios::app);
    const Scene& first = scenes.front().second;
    md << "\n#### Lattice sampler honesty on hard scenes (" << first.image.width << "x" << first.image.height
       << ", reference " << o.ref_spp << " spp sobol, seeds 1-" << o.seeds << ", " << bench::cpu_model() << ", "
       << embree_isa() << ")\n\n"
       << "Estimated / measured RMSE, min / median / max over the seeds; camera rays a pixel, mean over the seeds.\n\n"
       << "| scene | target | lattice est/measured | sobol est/measured | lattice rays/px | sobol rays/px |\n"
       << "|---|---|---|---|---:|---:|\n"
       << md_rows;
  }
  return 0;
}

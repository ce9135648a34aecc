// SPDX-License-Identifier: Apache-2.0
// Speed against error: renders a scene at spp = 1, 2, 4, ... for each sampler and measures render
// time, Mrays/s, RMSE and relMSE against a high-spp reference, next to the RMSE the renderer
// itself estimates (from each pixel's two independent sample streams). Then renders to a ladder
// of target errors (--target-rmse) and compares each with the uniform-spp render of the default
// sampler at the same measured error (interpolated in log-log on the uniform ladder). Prints JSON
// on stdout; writes markdown tables and gnuplot data files when asked. Asserts nothing about time.
//
//   speed_error --scene scenes/whitted.json --width 320 --height 180 --max-spp 1024
//               --ref-spp 4096 --cache DIR [--samplers sobol,cmj,independent,center]
//               [--center-max-spp 16] [--threads 0] [--targets auto|0.01,0.005]
//               [--markdown OUT.md] [--data OUT.dat] [--target-data OUT.dat]
//
// Times are CPU-seconds of the process (all render threads), which a shared machine disturbs less
// than wall time; wall time is reported too.
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

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
double relmse(const ImageRGB& a, const ImageRGB& ref);

struct Point {
  std::string sampler;
  int spp = 0;
  double seconds = 0, cpu_seconds = 0, mrays = 0, rmse = 0, relmse = 0, est_rmse = 0;
  uint64_t rays = 0;
  // Target-error renders only: "frame" (--target-rmse) or "block" (--block-rmse).
  std::string mode;
  double target = 0, mean_spp = 0;
  uint32_t min_spp = 0, max_spp = 0;
  int64_t unconverged_pixels = 0;
  double uniform_cpu_seconds = 0, uniform_spp = 0;  // the default sampler's uniform render at equal RMSE
  bool extrapolated = false;
};

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// Renders and measures one point: the mean over `seeds` renders with seeds 1..N of the times, the
// sample counts, the squared error and the squared estimate. One render's error is a heavy-tailed
// number where a few pixels (a bright edge seen through glass) hold most of it, while the
// estimate is a statement about the expected error: comparing means over seeds compares like
// with like.
//
// Each seed's render is timed as the fastest of up to `repeats` runs while a run takes under a
// CPU-second: the frame is the same bits every time, and on a shared machine other work only
// ever adds time (renders of 0.04-0.1 s were seen to swing 1.5x between runs of one binary, which
// is most of a target-error speed-up).
Point measure(const Scene& base, int threads, const ImageRGB& ref, int seeds, int repeats) {
  Point p;
  p.sampler = sampler_name(base.image.sampler);
  p.spp = base.image.spp;
  double mse = 0, est = 0, rel = 0;
  p.min_spp = ~0u;
  for (int k = 0; k < seeds; ++k) {
    Scene s = base;
    s.image.seed = base.image.seed + uint64_t(k);
    RenderScene rs(s, 0);
    double c0 = cpu_seconds();
    const FrameResult r = render_frame(rs, 32, threads);
    double best_cpu = cpu_seconds() - c0, best_wall = r.seconds;
    for (int k2 = 1; k2 < repeats && best_cpu < 1.0; ++k2) {
      c0 = cpu_seconds();
      const double wall = render_frame(rs, 32, threads).seconds;
      best_cpu = std::min(best_cpu, cpu_seconds() - c0);
      best_wall = std::min(best_wall, wall);
    }
    p.cpu_seconds += best_cpu / seeds;
    p.seconds += best_wall / seeds;
    p.rays += r.rays.total() / uint64_t(seeds);
    const double e = rmse(r.image, ref);
    mse += e * e / seeds;
    rel += relmse(r.image, ref) / seeds;
    const SampleSummary sum = r.summary();
    est += sum.estimated_rmse * sum.estimated_rmse / seeds;
    p.mean_spp += sum.mean_spp / seeds;
    p.min_spp = std::min(p.min_spp, sum.min_spp);
    p.max_spp = std::max(p.max_spp, sum.max_spp);
    p.unconverged_pixels += sum.unconverged_pixels;
  }
  p.mrays = double(p.rays) / p.seconds / 1e6;
  p.rmse = std::sqrt(mse);
  p.relmse = rel;
  p.est_rmse = std::sqrt(est);
  return p;
}

// log-log interpolation of `y` at the RMSE `e` along a ladder of points (RMSE falling); beyond
// its ends, the nearest segment's line (flagged).
double at_rmse(const std::vector<Point>& ladder, double e, double Point::*y, bool* extrapolated) {
  std::vector<const Point*> pts;
  for (const Point& p : ladder) {
    if (p.rmse > 0 && p.*y > 0) pts.push_back(&p);
  }
  if (pts.size() < 2) return 0;
  size_t k = 0;
  while (k + 2 < pts.size() && pts[k + 1]->rmse > e) ++k;
  const Point& a = *pts[k];
  const Point& b = *pts[k + 1];
  *extrapolated = e > pts.front()->rmse || e < pts.back()->rmse;
  const double t = (std::log(e) - std::log(a.rmse)) / (std::log(b.rmse) - std::log(a.rmse));
  return std::exp(std::log(a.*y) + t * (std::log(b.*y) - std::log(a.*y)));
}

// Relative MSE as in the denoising literature: mean of (x - ref)^2 / (ref^2 + 0.01).
double relmse(const ImageRGB& a, const ImageRGB& ref) {
  double s = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = double(a.rgb[i]) - double(ref.rgb[i]);
    s += d * d / (double(ref.rgb[i]) * double(ref.rgb[i]) + 0.01);
  }
  return s / double(a.rgb.size());
}

// Least-squares fit of log(rmse) = a + b log(CPU seconds); returns {a, b}.
std::pair<double, double> fit_loglog(const std::vector<Point>& pts) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const Point& p : pts) {
    if (!(p.cpu_seconds > 0) || !(p.rmse > 0)) continue;
    const double x = std::log(p.cpu_seconds), y = std::log(p.rmse);
    n += 1;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  if (n < 2) return {0, 0};
  const double b = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  return {(sy - b * sx) / n, b};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Speed against error: time, Mrays/s and RMSE against a reference, per sampler and spp"};
  std::string scene_path, cache_dir = "bench-cache", markdown, data;
  int width = 320, height = 180, max_spp = 1024, ref_spp = 4096, threads = 0, center_max_spp = 16;
  std::string samplers_arg = "sobol,cmj,independent,center";
  std::string targets_arg = "auto", target_data;
  int min_spp = 2, block_min_spp = 16, seeds = 3, repeats = 3;
  double target_rmse = 0.01;
  app.add_option("--scene", scene_path, "Scene JSON")->required()->check(CLI::ExistingFile);
  app.add_option("--width", width)->check(CLI::Range(1, 16384));
  app.add_option("--height", height)->check(CLI::Range(1, 16384));
  app.add_option("--max-spp", max_spp)->check(CLI::Range(1, 65536));
  app.add_option("--ref-spp", ref_spp, "Reference spp (stratified), cached in --cache")->check(CLI::Range(1, 65536));
  app.add_option("--center-max-spp", center_max_spp,
                 "The center sampler repeats one position: stop it early")->check(CLI::Range(1, 65536));
  app.add_option("--threads", threads, "Render threads (0 = all cores)")->check(CLI::Range(0, 4096));
  app.add_option("--samplers", samplers_arg, "Comma-separated: sobol, cmj, independent, center");
  app.add_option("--target-rmse", target_rmse, "Error for the fitted time-to-error column");
  app.add_option("--targets", targets_arg,
                 "Target errors for the target-error renders: comma-separated, 'auto' (a ladder between the "
                 "default sampler's uniform errors at 8 spp and at --max-spp/4) or 'none'");
  app.add_option("--repeats", repeats, "Each render's time: the fastest of this many runs (while a run takes under a CPU-second)")
      ->check(CLI::Range(1, 16));
  app.add_option("--seeds", seeds, "Renders per point (seeds 1..N): times, errors and estimates are their means")
      ->check(CLI::Range(1, 64));
  app.add_option("--min-spp", min_spp, "Frame-target renders (--target-rmse): fewest samples per pixel")
      ->check(CLI::Range(2, 65536));
  app.add_option("--block-min-spp", block_min_spp, "Block-bound renders (--block-rmse): fewest samples per pixel")
      ->check(CLI::Range(2, 65536));
  bool no_block = false;
  app.add_flag("--no-block", no_block, "Skip the block-bound renders");
  bool no_lattice = false;
  app.add_flag("--no-lattice", no_lattice, "Skip the frame-target renders with the lattice sampler");
  app.add_option("--target-data", target_data, "Write gnuplot data of the target-error renders to this file");
  app.add_option("--cache", cache_dir, "Directory for cached reference images");
  app.add_option("--markdown", markdown, "Append a markdown table to this file");
  app.add_option("--data", data, "Write gnuplot data (one block per sampler) to this file");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  std::vector<SamplerKind> samplers;
  {
    std::stringstream ss(samplers_arg);
    std::string name;
    while (std::getline(ss, name, ',')) {
      const auto k = sampler_from_name(name);
      if (!k) {
        std::cerr << "speed_error: --samplers: unknown sampler '" << name << "' (stratified, independent, center)\n";
        return 2;
      }
      samplers.push_back(*k);
    }
  }
  Scene scene;
  try {
    scene = load_scene(scene_path);
  } catch (const std::exception& e) {
    std::cerr << "speed_error: " << e.what() << "\n";
    return 2;
  }
  const std::string name = fs::path(scene_path).stem().string();
  scene.image.width = width;
  scene.image.height = height;

  // The reference: the default sampler at ref_spp, a different seed than the runs measured against it
  // (so its own noise is independent of theirs), cached because it is by far the slowest part.
  fs::create_directories(cache_dir);
  const std::string ref_path = cache_dir + "/" + name + "_" + std::to_string(width) + "x" +
                               std::to_string(height) + "_ref" + std::to_string(ref_spp) + "_sobol.exr";
  ImageRGB ref;
  double ref_est_rmse = 0;
  if (fs::exists(ref_path)) {
    ExrAttributes attrs;
    ref = read_exr(ref_path, &attrs);
    if (auto it = attrs.find("tessera:estimatedRmse"); it != attrs.end()) ref_est_rmse = std::get<double>(it->second);
  } else {
    Scene rs_scene = scene;
    rs_scene.image.spp = ref_spp;
    rs_scene.image.sampler = SamplerKind::kSobol;
    rs_scene.image.seed = scene.image.seed + 1000;
    RenderScene rs(rs_scene, 0);
    const FrameResult r = render_frame(rs, 32, threads);
    ref = r.image;
    ref_est_rmse = r.estimated_rmse();
    write_exr(ref_path, ref, {{"tessera:spp", int64_t(ref_spp)}, {"tessera:estimatedRmse", ref_est_rmse},
                              {"tessera:renderSeconds", r.seconds}});
    std::cerr << "speed_error: reference " << ref_path << " rendered in " << r.seconds << " s\n";
  }

  std::vector<Point> points;
  for (SamplerKind k : samplers) {
    const int top = k == SamplerKind::kCenter ? std::min(max_spp, center_max_spp) : max_spp;
    for (int spp = 1; spp <= top; spp *= 2) {
      Scene s = scene;
      s.image.spp = spp;
      s.image.sampler = k;
      s.image.target_rmse = 0;
      const Point p = measure(s, threads, ref, seeds, repeats);
      points.push_back(p);
      std::cerr << "  " << name << " " << p.sampler << " " << spp << " spp: " << p.seconds << " s, rmse " << p.rmse
                << "\n";
    }
  }

  // Fitted time to reach target_rmse, per sampler, from the points with spp >= 4 (the
  // asymptotic regime; spp 1-2 are dominated by fixed costs).
  nlohmann::json fits = nlohmann::json::object();
  std::map<std::string, double> time_to_target;
  for (SamplerKind k : samplers) {
    std::vector<Point> pts;
    for (const Point& p : points) {
      if (p.sampler == sampler_name(k) && p.spp >= 4) pts.push_back(p);
    }
    const auto [a, b] = fit_loglog(pts);
    // A flat line (the center sampler: its error is aliasing, which more samples do not
    // remove) never reaches the target: -1, not a meaningless extrapolation.
    const double t = b < -0.05 ? std::exp((std::log(target_rmse) - a) / b) : -1;
    time_to_target[sampler_name(k)] = t;
    fits[sampler_name(k)] = {{"log_rmse_intercept", a}, {"slope", b}, {"seconds_to_target", t}};
  }

  // Honesty of the estimate: est/RMSE over every uniform render at spp >= 8, per sampler.
  nlohmann::json honesty = nlohmann::json::object();
  for (SamplerKind k : samplers) {
    if (k == SamplerKind::kCenter) continue;  // biased: its error is aliasing, which no estimate sees
    double lo = 1e30, hi = 0;
    for (const Point& p : points) {
      if (p.sampler != sampler_name(k) || p.spp < 8 || !(p.rmse > 0)) continue;
      lo = std::min(lo, p.est_rmse / p.rmse);
      hi = std::max(hi, p.est_rmse / p.rmse);
    }
    if (hi > 0) honesty[sampler_name(k)] = {{"min_ratio", lo}, {"max_ratio", hi}, {"within_0.8_1.25", lo >= 0.8 && hi <= 1.25}};
  }

  // Target-error renders against the default sampler's uniform ladder.
  std::vector<Point> uniform;
  for (const Point& p : points) {
    if (p.sampler == sampler_name(SamplerKind::kSobol) && p.spp >= 4) uniform.push_back(p);
  }
  std::vector<double> targets;
  if (targets_arg == "auto" && uniform.size() >= 2) {
    double hi = 0, lo = 0;
    for (const Point& p : uniform) {
      if (p.spp == 8) hi = p.rmse;
      if (p.spp <= std::max(8, max_spp / 4)) lo = p.rmse;
    }
    for (int i = 0; i < 5 && hi > 0 && lo > 0; ++i) targets.push_back(hi * std::pow(lo / hi, i / 4.0));
  } else if (targets_arg != "auto" && targets_arg != "none") {
    std::stringstream ss(targets_arg);
    std::string t;
    while (std::getline(ss, t, ',')) targets.push_back(std::stod(t));
  }
  // Each target twice: as the frame's error (--target-rmse) and as every block's (--block-rmse).
  std::vector<Point> adaptive;
  // And the frame's error with the lattice sampler (render/lattice_sampler.h), unless --no-lattice.
  for (const std::string mode : {"frame", "block", "lattice"}) {
  if (mode == "block" && no_block) continue;
  if (mode == "lattice" && no_lattice) continue;
  for (double t : targets) {
    Scene s = scene;
    s.image.sampler = mode == "lattice" ? SamplerKind::kLattice : SamplerKind::kSobol;
    (mode == "block" ? s.image.block_rmse : s.image.target_rmse) = t;
    s.image.min_spp = mode == "block" ? block_min_spp : min_spp;
    s.image.max_spp = max_spp;
    Point p = measure(s, threads, ref, seeds, repeats);
    p.mode = mode;
    p.target = t;
    p.spp = 0;
    p.uniform_cpu_seconds = at_rmse(uniform, p.rmse, &Point::cpu_seconds, &p.extrapolated);
    bool ex2 = false;
    std::vector<Point> with_spp = uniform;
    for (Point& u : with_spp) u.mean_spp = u.spp;
    p.uniform_spp = at_rmse(with_spp, p.rmse, &Point::mean_spp, &ex2);
    adaptive.push_back(p);
    std::cerr << "  " << name << " " << mode << " target " << t << ": " << p.cpu_seconds << " cpu-s, mean spp " << p.mean_spp
              << ", rmse " << p.rmse << ", uniform at equal rmse " << p.uniform_cpu_seconds << " cpu-s\n";
  }
  }

  nlohmann::json out;
  out["scene"] = name;
  out["width"] = width;
  out["height"] = height;
  out["max_depth"] = scene.image.max_depth;
  out["threads"] = threads;
  out["reference"] = {{"spp", ref_spp}, {"sampler", "sobol"}, {"estimated_rmse", ref_est_rmse}};
  out["honesty"] = honesty;
  out["renderer"] = embree_isa();
  out["target_rmse"] = target_rmse;
  out["seeds"] = seeds;
  out["fits"] = fits;
  for (const Point& p : points) {
    out["runs"].push_back({{"sampler", p.sampler}, {"spp", p.spp}, {"seconds", p.seconds},
                           {"cpu_seconds", p.cpu_seconds}, {"rays", p.rays}, {"mrays_per_s", p.mrays},
                           {"rmse", p.rmse}, {"relmse", p.relmse}, {"estimated_rmse", p.est_rmse}});
  }
  out["target_runs"] = nlohmann::json::array();
  for (const Point& p : adaptive) {
    out["target_runs"].push_back(
        {{"mode", p.mode}, {"target_rmse", p.target}, {"min_spp", p.mode == "block" ? block_min_spp : min_spp},
         {"max_spp", max_spp}, {"seconds", p.seconds},
         {"cpu_seconds", p.cpu_seconds}, {"mean_spp", p.mean_spp}, {"spp_min", p.min_spp}, {"spp_max", p.max_spp},
         {"rmse", p.rmse}, {"estimated_rmse", p.est_rmse}, {"unconverged_pixels", p.unconverged_pixels},
         {"uniform_cpu_seconds_at_equal_rmse", p.uniform_cpu_seconds}, {"uniform_spp_at_equal_rmse", p.uniform_spp},
         {"speedup", p.uniform_cpu_seconds > 0 ? p.uniform_cpu_seconds / p.cpu_seconds : 0.0},
         {"extrapolated", p.extrapolated}});
  }
  std::cout << out.dump(2) << "\n";

  if (!markdown.empty()) {
    std::ofstream md(markdown, std::ios::app);
    char buf[512];
    md << "\n#### " << name << " (" << width << "x" << height << ", max_depth " << scene.image.max_depth
       << ", reference " << ref_spp << " spp sobol, its estimated RMSE " << ref_est_rmse << "; every row the mean of "
       << seeds << " seeds: RMSE and estimate as root mean squares; each render's time the fastest of " << repeats
       << " runs)\n\n";
    md << "| sampler | spp | time (s) | CPU (s) | Mrays/s | RMSE | relMSE | estimated RMSE | est/RMSE |\n";
    md << "|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const Point& p : points) {
      std::snprintf(buf, sizeof buf, "| %s | %d | %.3f | %.3f | %.2f | %.4g | %.4g | %.4g | %.2f |\n", p.sampler.c_str(),
                    p.spp, p.seconds, p.cpu_seconds, p.mrays, p.rmse, p.relmse, p.est_rmse,
                    p.rmse > 0 ? p.est_rmse / p.rmse : 0.0);
      md << buf;
    }
    md << "\nestimated/measured RMSE at spp >= 8:";
    for (auto& [k, v] : honesty.items()) {
      std::snprintf(buf, sizeof buf, " %s %.2f-%.2f%s;", k.c_str(), v["min_ratio"].get<double>(),
                    v["max_ratio"].get<double>(), v["within_0.8_1.25"].get<bool>() ? "" : " (OUTSIDE 0.8-1.25)");
      md << buf;
    }
    md << "\n";
    if (!adaptive.empty()) {
      md << "\nTarget-error renders (sobol, max_spp " << max_spp << "; frame: --target-rmse, min_spp " << min_spp
         << "; block: --block-rmse, min_spp " << block_min_spp
         << "; lattice: --target-rmse --sampler lattice) against uniform sobol at the same measured RMSE:\n\n";
      md << "| mode | target | CPU (s) | mean spp | spp range | RMSE | est. RMSE | est/RMSE | RMSE/target | uniform CPU (s) at that RMSE | uniform spp | speed-up |\n";
      md << "|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|\n";
      for (const Point& p : adaptive) {
        std::snprintf(buf, sizeof buf, "| %s | %.3g | %.3f | %.1f | %u-%u | %.4g | %.4g | %.2f | %.2f | %.3f%s | %.0f | %.2fx |\n",
                      p.mode.c_str(), p.target, p.cpu_seconds, p.mean_spp, p.min_spp, p.max_spp, p.rmse, p.est_rmse,
                      p.rmse > 0 ? p.est_rmse / p.rmse : 0.0, p.rmse / p.target, p.uniform_cpu_seconds,
                      p.extrapolated ? " (extrap.)" : "",
                      p.uniform_spp, p.uniform_cpu_seconds > 0 ? p.uniform_cpu_seconds / p.cpu_seconds : 0.0);
        md << buf;
      }
    }
    md << "\nFitted log-log slope of RMSE against time, and time to reach RMSE " << target_rmse << ":";
    for (SamplerKind k : samplers) {
      const auto& f = fits[sampler_name(k)];
      const double t = f["seconds_to_target"].get<double>();
      std::snprintf(buf, sizeof buf, " %s slope %.2f, %s;", sampler_name(k), f["slope"].get<double>(),
                    t > 0 ? (std::to_string(t).substr(0, 8) + " s").c_str() : "never (error does not fall)");
      md << buf;
    }
    md << "\n";
  }
  if (!data.empty()) {
    std::ofstream dat(data);
    for (SamplerKind k : samplers) {
      dat << "# " << sampler_name(k) << "\n# cpu_seconds rmse estimated_rmse spp\n";
      for (const Point& p : points) {
        if (p.sampler == sampler_name(k)) dat << p.cpu_seconds << " " << p.rmse << " " << p.est_rmse << " " << p.spp << "\n";
      }
      dat << "\n\n";
    }
  }
  if (!target_data.empty()) {
    std::ofstream dat(target_data);
    dat << "# frame-target renders (sobol, --target-rmse)\n# cpu_seconds rmse estimated_rmse mean_spp target\n";
    for (const Point& p : adaptive) {
      if (p.mode != "frame") continue;
      dat << p.cpu_seconds << " " << p.rmse << " " << p.est_rmse << " " << p.mean_spp << " " << p.target << "\n";
    }
  }
  return 0;
}

// Speed against error (issue 6, part 1): renders a scene at spp = 1, 2, 4, ... for each sampler
// and measures render time, Mrays/s, RMSE and relMSE against a high-spp reference, next to the
// RMSE the renderer itself estimates from the per-pixel sample variance. Prints JSON on stdout;
// writes a markdown table and a gnuplot data file when asked. Asserts nothing about time.
//
//   speed_error --scene scenes/whitted.json --width 320 --height 180 --max-spp 1024
//               --ref-spp 4096 --cache DIR [--samplers stratified,independent,center]
//               [--center-max-spp 16] [--threads 0] [--target-rmse 0.01]
//               [--markdown OUT.md] [--data OUT.dat]
#include <spdlog/spdlog.h>

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

#include "image/exr_io.h"
#include "render/embree_device.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"

namespace fs = std::filesystem;
using namespace tessera;

namespace {

struct Point {
  std::string sampler;
  int spp = 0;
  double seconds = 0, mrays = 0, rmse = 0, relmse = 0, est_rmse = 0;
  uint64_t rays = 0;
};

// RMSE over all pixels and channels, in linear light.
double rmse(const ImageRGB& a, const ImageRGB& ref) {
  double s = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = double(a.rgb[i]) - double(ref.rgb[i]);
    s += d * d;
  }
  return std::sqrt(s / double(a.rgb.size()));
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

// Least-squares fit of log(rmse) = a + b log(seconds); returns {a, b}.
std::pair<double, double> fit_loglog(const std::vector<Point>& pts) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const Point& p : pts) {
    if (!(p.seconds > 0) || !(p.rmse > 0)) continue;
    const double x = std::log(p.seconds), y = std::log(p.rmse);
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
  std::string samplers_arg = "stratified,independent,center";
  double target_rmse = 0.01;
  app.add_option("--scene", scene_path, "Scene JSON")->required()->check(CLI::ExistingFile);
  app.add_option("--width", width)->check(CLI::Range(1, 16384));
  app.add_option("--height", height)->check(CLI::Range(1, 16384));
  app.add_option("--max-spp", max_spp)->check(CLI::Range(1, 65536));
  app.add_option("--ref-spp", ref_spp, "Reference spp (stratified), cached in --cache")->check(CLI::Range(1, 65536));
  app.add_option("--center-max-spp", center_max_spp,
                 "The center sampler repeats one position: stop it early")->check(CLI::Range(1, 65536));
  app.add_option("--threads", threads, "Render threads (0 = all cores)")->check(CLI::Range(0, 4096));
  app.add_option("--samplers", samplers_arg, "Comma-separated: stratified, independent, center");
  app.add_option("--target-rmse", target_rmse, "Error for the fitted time-to-error column");
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

  // The reference: stratified at ref_spp, a different seed than the runs measured against it
  // (so its own noise is independent of theirs), cached because it is by far the slowest part.
  fs::create_directories(cache_dir);
  const std::string ref_path = cache_dir + "/" + name + "_" + std::to_string(width) + "x" +
                               std::to_string(height) + "_ref" + std::to_string(ref_spp) + ".exr";
  ImageRGB ref;
  double ref_est_rmse = 0;
  if (fs::exists(ref_path)) {
    ExrAttributes attrs;
    ref = read_exr(ref_path, &attrs);
    if (auto it = attrs.find("tessera:estimatedRmse"); it != attrs.end()) ref_est_rmse = std::get<double>(it->second);
  } else {
    Scene rs_scene = scene;
    rs_scene.image.spp = ref_spp;
    rs_scene.image.sampler = SamplerKind::kStratified;
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
      RenderScene rs(s, 0);
      const FrameResult r = render_frame(rs, 32, threads);
      Point p;
      p.sampler = sampler_name(k);
      p.spp = spp;
      p.seconds = r.seconds;
      p.rays = r.rays.total();
      p.mrays = double(p.rays) / r.seconds / 1e6;
      p.rmse = rmse(r.image, ref);
      p.relmse = relmse(r.image, ref);
      p.est_rmse = r.estimated_rmse();
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

  nlohmann::json out;
  out["scene"] = name;
  out["width"] = width;
  out["height"] = height;
  out["max_depth"] = scene.image.max_depth;
  out["threads"] = threads;
  out["reference"] = {{"spp", ref_spp}, {"sampler", "stratified"}, {"estimated_rmse", ref_est_rmse}};
  out["renderer"] = embree_isa();
  out["target_rmse"] = target_rmse;
  out["fits"] = fits;
  for (const Point& p : points) {
    out["runs"].push_back({{"sampler", p.sampler}, {"spp", p.spp}, {"seconds", p.seconds}, {"rays", p.rays},
                           {"mrays_per_s", p.mrays}, {"rmse", p.rmse}, {"relmse", p.relmse},
                           {"estimated_rmse", p.est_rmse}});
  }
  std::cout << out.dump(2) << "\n";

  if (!markdown.empty()) {
    std::ofstream md(markdown, std::ios::app);
    char buf[512];
    md << "\n#### " << name << " (" << width << "x" << height << ", max_depth " << scene.image.max_depth
       << ", reference " << ref_spp << " spp stratified, its estimated RMSE " << ref_est_rmse << ")\n\n";
    md << "| sampler | spp | time (s) | Mrays/s | RMSE | relMSE | estimated RMSE | est/RMSE |\n";
    md << "|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const Point& p : points) {
      std::snprintf(buf, sizeof buf, "| %s | %d | %.3f | %.2f | %.4g | %.4g | %.4g | %.2f |\n", p.sampler.c_str(), p.spp,
                    p.seconds, p.mrays, p.rmse, p.relmse, p.est_rmse, p.rmse > 0 ? p.est_rmse / p.rmse : 0.0);
      md << buf;
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
      dat << "# " << sampler_name(k) << "\n# seconds rmse estimated_rmse spp\n";
      for (const Point& p : points) {
        if (p.sampler == sampler_name(k)) dat << p.seconds << " " << p.rmse << " " << p.est_rmse << " " << p.spp << "\n";
      }
      dat << "\n\n";
    }
  }
  return 0;
}

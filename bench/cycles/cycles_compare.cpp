// SPDX-License-Identifier: Apache-2.0
// Blender's Cycles as a peer on a glTF scene: compares Cycles' render of a .glb
// (bench/cycles/cycles_render.py, run by bench/run_all.sh: Whitted-like transport, linear EXR)
// with Tessera's render of the same file at the same size and samples per pixel, in this
// process: RMSE in linear light of each against a high-spp Tessera reference, of the two against
// each other, mean level ratio, and samples per second (wall and CPU) of each.
//
// Where the two models disagree is masked, and the mask's share is reported: pixels whose camera
// ray meets glass (Cycles' Principled glass is not Tessera's two-branch Fresnel glass), and
// diffuse pixels lit through glass (Cycles blocks shadow rays at glass; Tessera attenuates them).
// Mirrors that show glass are not masked. Prints JSON on stdout; appends markdown to --markdown.
// Asserts nothing about time.
//
// Samples per second compare the render alone on both sides. Tessera's time leaves out its scene
// build (BVH) and EXR write. Cycles' timed render includes its scene synchronization (its BVH
// build) and the EXR write, a fixed cost that was 0.15 of 0.41 s of a 192x108, 16-spp render
// (its own "synchronization_time" metadata). Given Cycles' time for the same render at 1 spp
// (--cycles-one-spp-cpu, --cycles-one-spp-wall), that fixed cost is estimated from the two
// times, as Cycles' time is linear in spp past it, and taken out of Cycles' times.
//
// The bound (--ray-ceiling-json: bench/ray_ceiling's output for the same scene, size, spp and
// depth, one thread): the CPU time bare Embree takes to answer this frame's own queries (the same
// rays, the faster of 8- and 16-wide packets, Embree's robust triangles), against Cycles' render
// time. Tessera's samples can be no faster than their queries, so Cycles' time over that query
// time is the most Tessera / Cycles throughput any shading, sampling and accumulation code could
// reach with these rays; a goal of g times Cycles needs the renderer's whole frame within
// Cycles' time / g, which is a ray-ceiling ratio of g x query time / Cycles' time (reported as
// needed_ceiling_ratio, beside the ratio the renderer has now).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "../bench_host.h"
#include "image/exr_io.h"
#include "render/embree_device.h"
#include "render/render_scene_internal.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"

namespace fs = std::filesystem;
using namespace tessera;
using bench::cpu_model;

namespace {

// RMSE over the pixels where mask is 1 (an empty mask: every pixel).
double rmse(const ImageRGB& a, const ImageRGB& b, const std::vector<uint8_t>& mask = {}) {
  double s = 0;
  size_t n = 0;
  for (size_t p = 0; p < a.rgb.size() / 3; ++p) {
    if (!mask.empty() && !mask[p]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.rgb[3 * p + c]) - double(b.rgb[3 * p + c]);
      s += d * d;
    }
    n += 3;
  }
  return n ? std::sqrt(s / double(n)) : 0.0;
}

double mean(const ImageRGB& a, const std::vector<uint8_t>& mask) {
  double s = 0;
  size_t n = 0;
  for (size_t p = 0; p < a.rgb.size() / 3; ++p) {
    if (!mask[p]) continue;
    s += double(a.rgb[3 * p]) + a.rgb[3 * p + 1] + a.rgb[3 * p + 2];
    n += 3;
  }
  return n ? s / double(n) : 0.0;
}

// 1 where the two renderers' models agree (see the file comment), from each pixel's centre ray.
std::vector<uint8_t> agreement_mask(const RenderScene& rs) {
  const ImageSettings& img = rs.image();
  const auto& cam = rs.camera();
  std::vector<uint8_t> mask(size_t(img.width) * img.height, 1);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const Vec3f d = normalize(cam.p0 + cam.du * ((x + 0.5f) / img.width) + cam.dv * ((y + 0.5f) / img.height));
      Hit h;
      if (!rs.intersect(Ray{Vec3f(0.0f), d}, PrimRef{}, &h)) continue;
      const Material& m = rs.material(h.material);
      uint8_t& keep = mask[size_t(y) * img.width + x];
      if (m.type == Material::Type::kGlass) {
        keep = 0;
        continue;
      }
      if (m.type != Material::Type::kDiffuse) continue;
      const Vec3f n = dot(d, h.n) < 0 ? h.n : -h.n;
      // Lit through glass: the shadow ray's first surface is glass and the light still arrives.
      auto through_glass = [&](const Vec3f& w, float dist) {
        if (!(dot(n, w) > 0)) return false;
        const Ray r{offset_ray_origin(h.p, h.p_err, n, w), w, dist};
        Hit g;
        if (!rs.intersect(r, h.prim, &g) || rs.material(g.material).type != Material::Type::kGlass) return false;
        const Rgb T = rs.transmittance(r, h.prim);
        return T.x > 0 || T.y > 0 || T.z > 0;
      };
      for (const auto& l : rs.point_lights()) keep &= !through_glass(normalize(l.position - h.p), length(l.position - h.p));
      for (const auto& l : rs.spot_lights()) keep &= !through_glass(normalize(l.position - h.p), length(l.position - h.p));
      for (const auto& l : rs.directional_lights()) keep &= !through_glass(-l.direction, INFINITY);
    }
  }
  return mask;
}

struct Run {
  double wall = 0, cpu = 0;
  ImageRGB image;
};

// The fastest of `reps` renders by CPU time (every one gives the same image): on a shared machine
// one render's time moved 1.7x between runs. run_all.sh keeps the faster of Cycles' runs too.
Run render(const Scene& base, int spp, int threads, double target_rmse = 0, int reps = 1) {
  Scene s = base;
  s.image.spp = spp;
  s.image.target_rmse = target_rmse;
  RenderScene rs(s, 0);
  Run best;
  for (int i = 0; i < reps; ++i) {
    const double c0 = bench::process_cpu_seconds();
    FrameResult r = render_frame(rs, 32, threads);
    const double cpu = bench::process_cpu_seconds() - c0;
    if (i > 0 && cpu >= best.cpu) continue;
    best = {r.seconds, cpu, std::move(r.image)};
  }
  return best;
}

// Blender's time stamps, "MM:SS.cc" or "HH:MM:SS.cc", in seconds; -1 if absent or malformed.
double stamp_seconds(const ExrAttributes& attrs, const std::string& name) {
  const auto it = attrs.find(name);
  if (it == attrs.end() || !std::holds_alternative<std::string>(it->second)) return -1;
  const std::string& text = std::get<std::string>(it->second);
  double total = 0;
  size_t start = 0;
  try {
    for (;;) {
      const size_t colon = text.find(':', start);
      total = total * 60 + std::stod(text.substr(start, colon - start));
      if (colon == std::string::npos) return total;
      start = colon + 1;
    }
  } catch (const std::exception&) {
    return -1;
  }
}

// Cycles' fixed cost from its time at spp and at 1 spp: t = fixed + spp * per_sample.
double fixed_cost(double t, double t1, int spp) {
  if (t1 <= 0 || spp <= 1) return 0;
  return t1 - (t - t1) / double(spp - 1);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Tessera against Blender's Cycles on a glTF scene"};
  std::string scene_path, cycles_exr, cycles_ref_exr, markdown;
  int width = 192, height = 108, threads = 0, spp = 16, ref_spp = 1024, max_depth = 8;
  double cycles_wall = 0, cycles_cpu = 0;
  app.add_option("--scene", scene_path, "The .glb both render")->required()->check(CLI::ExistingFile);
  app.add_option("--cycles-exr", cycles_exr, "Cycles' linear EXR (cycles_render.py)")->required()->check(CLI::ExistingFile);
  app.add_option("--cycles-wall", cycles_wall, "Cycles' render time, wall seconds (its CYCLES_RESULT line)")->required();
  app.add_option("--cycles-cpu", cycles_cpu, "Cycles' render CPU-seconds")->required();
  double one_spp_wall = 0, one_spp_cpu = 0;
  app.add_option("--cycles-one-spp-wall", one_spp_wall,
                 "Cycles' wall seconds for the same render at 1 spp: its fixed cost is then taken out of its times");
  app.add_option("--cycles-one-spp-cpu", one_spp_cpu, "The same in CPU-seconds");
  app.add_option("--cycles-reference-exr", cycles_ref_exr,
                 "Optional: Cycles at --ref-spp; then the two references' RMSE measures where the models differ, "
                 "noise apart")->check(CLI::ExistingFile);
  app.add_option("--spp", spp, "Samples per pixel of both renders");
  app.add_option("--ref-spp", ref_spp, "Samples per pixel of the Tessera reference");
  app.add_option("--max-depth", max_depth, "Tessera's max_depth (Cycles' glossy/transmission bounces)");
  app.add_option("--width", width);
  app.add_option("--height", height);
  app.add_option("--threads", threads, "Tessera threads (give Cycles the same)");
  app.add_option("--markdown", markdown);
  // Time to equal error against Cycles' adaptive sampling: Cycles' error against its own
  // reference (--cycles-reference-exr), Tessera's against its own, so that where the two models
  // differ counts against neither; Tessera renders to a frame target from 1.3x Cycles' error down
  // in steps of 5% until it is at most Cycles'.
  std::string adaptive_exr;
  double adaptive_wall = 0, adaptive_cpu = 0, adaptive_threshold = 0;
  int adaptive_max_spp = 1024;
  app.add_option("--cycles-adaptive-exr", adaptive_exr, "Cycles with adaptive sampling (cycles_render.py's threshold)")
      ->check(CLI::ExistingFile);
  app.add_option("--cycles-adaptive-wall", adaptive_wall, "Its render time, wall seconds");
  app.add_option("--cycles-adaptive-cpu", adaptive_cpu, "Its render CPU-seconds");
  app.add_option("--cycles-adaptive-threshold", adaptive_threshold, "Its noise threshold, for the tables");
  app.add_option("--cycles-adaptive-max-spp", adaptive_max_spp, "Its most samples per pixel, for the tables");
  std::string ceiling_json;
  double goal = 3.0;
  app.add_option("--ray-ceiling-json", ceiling_json,
                 "bench/ray_ceiling's JSON for the same scene, size, spp and depth: the bound on the throughput ratio")
      ->check(CLI::ExistingFile);
  app.add_option("--goal", goal, "The throughput goal the bound is read against (Tessera / Cycles samples per CPU-second)")
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::err);
  // The ray ceiling's JSON, checked before any render: it must be of this comparison's frame.
  nlohmann::json ceiling;
  if (!ceiling_json.empty()) {
    try {
      ceiling = nlohmann::json::parse(std::ifstream(ceiling_json));
      for (const auto& [key, want] : {std::pair<const char*, int>{"width", width}, {"height", height}, {"spp", spp},
                                      {"max_depth", max_depth}, {"threads", 1}}) {
        if (ceiling.at(key).get<int>() != want) {
          std::cerr << "cycles_compare: " << ceiling_json << ": field \"" << key << "\" is " << ceiling.at(key)
                    << ", this comparison's is " << want << "\n";
          return 2;
        }
      }
      for (const char* key : {"camera", "shadow", "secondary"}) ceiling.at("rays").at(key).get<double>();
      ceiling.at("robust_ceiling").at("best_packet_mrays_per_s").get<double>();
      ceiling.at("robust_ceiling").at("ratio").get<double>();
      ceiling.at("seconds").at("renderer").get<double>();
    } catch (const std::exception& e) {
      std::cerr << "cycles_compare: " << ceiling_json << ": not bench/ray_ceiling's JSON (" << e.what() << ")\n";
      return 2;
    }
  }

  Scene scene = load_scene(scene_path);
  ImageOverrides o;
  o.width = width;
  o.height = height;
  o.max_depth = max_depth;
  o.spp = spp;
  apply_overrides(scene, o);
  const ImageRGB cycles = read_exr(cycles_exr);
  if (cycles.width != width || cycles.height != height) {
    std::cerr << "cycles_compare: Cycles' image is " << cycles.width << "x" << cycles.height << ", expected " << width
              << "x" << height << "\n";
    return 2;
  }
  const Run ref = render(scene, ref_spp, threads);
  const Run same = render(scene, spp, threads, 0, 3);
  const std::vector<uint8_t> mask = agreement_mask(RenderScene(scene, 0));
  size_t kept = 0;
  for (uint8_t m : mask) kept += m;
  const double px = double(width) * height;
  double fixed_wall = fixed_cost(cycles_wall, one_spp_wall, spp);
  double fixed_cpu = fixed_cost(cycles_cpu, one_spp_cpu, spp);
  // Where the two times do not fit (a noise spike, or renders so small that the fixed cost is all
  // of both), nothing is taken out, and the JSON and the table say so: Cycles' whole time then
  // counts, which flatters Tessera.
  bool fitted = one_spp_cpu > 0 && one_spp_wall > 0 && spp > 1;
  if (fitted && (fixed_wall < 0 || fixed_cpu < 0 || !(cycles_wall - fixed_wall > 0) || !(cycles_cpu - fixed_cpu > 0))) {
    std::cerr << "cycles_compare: Cycles' 1-spp times (" << one_spp_wall << " s wall, " << one_spp_cpu
              << " s CPU) do not fit its " << spp << "-spp times (" << cycles_wall << ", " << cycles_cpu
              << "): its fixed cost is not taken out, which flatters Tessera; run again on a quieter machine\n";
    fitted = false;
  }
  if (!fitted) fixed_wall = fixed_cpu = 0;
  const double render_wall = cycles_wall - fixed_wall, render_cpu = cycles_cpu - fixed_cpu;
  ExrAttributes cycles_attrs;
  read_exr(cycles_exr, &cycles_attrs);
  const double own_sync = stamp_seconds(cycles_attrs, "cycles.ViewLayer.synchronization_time");
  const double own_render = stamp_seconds(cycles_attrs, "cycles.ViewLayer.render_time");
  const double t_sps_wall = px * spp / same.wall, t_sps_cpu = px * spp / same.cpu;
  const double c_sps_wall = px * spp / render_wall, c_sps_cpu = px * spp / render_cpu;
  nlohmann::json out = {
      {"scene", fs::path(scene_path).filename().string()},
      {"width", width},
      {"height", height},
      {"spp", spp},
      {"max_depth", max_depth},
      {"threads", threads},
      {"cpu", cpu_model()},
      {"renderer", embree_isa()},
      {"reference_spp", ref_spp},
      {"agreement_mask_fraction", double(kept) / px},
      {"cycles", {{"wall_s", cycles_wall}, {"cpu_s", cycles_cpu},
                  {"fixed_cost", {{"taken_out", fitted}, {"wall_s", fixed_wall}, {"cpu_s", fixed_cpu}, {"one_spp_wall_s", one_spp_wall},
                                  {"one_spp_cpu_s", one_spp_cpu}}},
                  {"render_wall_s", render_wall}, {"render_cpu_s", render_cpu},
                  {"own_metadata", {{"synchronization_wall_s", own_sync}, {"render_wall_s", own_render}}},
                  {"samples_per_s_wall", c_sps_wall},
                  {"samples_per_s_cpu", c_sps_cpu}, {"rmse_vs_reference", rmse(cycles, ref.image)},
                  {"rmse_vs_reference_masked", rmse(cycles, ref.image, mask)},
                  {"mean_ratio_to_reference_masked", mean(cycles, mask) / mean(ref.image, mask)}}},
      {"tessera", {{"wall_s", same.wall}, {"cpu_s", same.cpu}, {"samples_per_s_wall", t_sps_wall},
                   {"samples_per_s_cpu", t_sps_cpu}, {"rmse_vs_reference", rmse(same.image, ref.image)},
                   {"rmse_vs_reference_masked", rmse(same.image, ref.image, mask)}}},
      {"rmse_cycles_vs_tessera", rmse(cycles, same.image)},
      {"rmse_cycles_vs_tessera_masked", rmse(cycles, same.image, mask)},
      {"throughput_ratio_wall", t_sps_wall / c_sps_wall},
      {"throughput_ratio_cpu", t_sps_cpu / c_sps_cpu},
      // The old measure, kept for comparison: Cycles' fixed cost counted as rendering.
      {"throughput_ratio_cpu_with_cycles_fixed_cost", t_sps_cpu * cycles_cpu / (px * spp)}};
  if (!ceiling.is_null()) {
    const double query = ceiling["robust_ceiling"]["best_packet_mrays_per_s"].get<double>();
    const auto& rays = ceiling["rays"];
    const double n = rays["camera"].get<double>() + rays["shadow"].get<double>() + rays["secondary"].get<double>();
    const double query_s = n / (query * 1e6);
    out["bound"] = {{"ray_ceiling_json", ceiling_json},
                    {"rays", n},
                    {"rays_per_sample", n / (px * spp)},
                    {"bare_query_cpu_s", query_s},
                    {"renderer_cpu_s_one_thread", ceiling["seconds"]["renderer"]},
                    {"cycles_render_cpu_s", render_cpu},
                    {"max_throughput_ratio_cpu", render_cpu / query_s},
                    {"goal", goal},
                    {"needed_ceiling_ratio", goal * query_s / render_cpu},
                    {"ceiling_ratio_now", ceiling["robust_ceiling"]["ratio"]}};
  }
  if (!cycles_ref_exr.empty()) {
    const ImageRGB cref = read_exr(cycles_ref_exr);
    if (cref.width != width || cref.height != height) {
      std::cerr << "cycles_compare: Cycles' reference is " << cref.width << "x" << cref.height << "\n";
      return 2;
    }
    out["references"] = {{"rmse", rmse(cref, ref.image)}, {"rmse_masked", rmse(cref, ref.image, mask)},
                         {"mean_ratio_masked", mean(cref, mask) / mean(ref.image, mask)}};
    if (!adaptive_exr.empty()) {
      const ImageRGB ca = read_exr(adaptive_exr);
      if (ca.width != width || ca.height != height) {
        std::cerr << "cycles_compare: Cycles' adaptive render is " << ca.width << "x" << ca.height << "\n";
        return 2;
      }
      const double c_err = rmse(ca, cref);
      Run t;
      double target = 1.3 * c_err, t_err = 0;
      for (int i = 0; i < 40; ++i, target *= 0.95) {
        t = render(scene, spp, threads, target);
        t_err = rmse(t.image, ref.image);
        if (t_err <= c_err) break;
      }
      out["adaptive"] = {{"cycles", {{"noise_threshold", adaptive_threshold}, {"max_spp", adaptive_max_spp}, {"wall_s", adaptive_wall},
                                     {"cpu_s", adaptive_cpu}, {"rmse_vs_own_reference", c_err}}},
                         {"tessera", {{"target_rmse", target}, {"wall_s", t.wall}, {"cpu_s", t.cpu},
                                      {"rmse_vs_own_reference", t_err}, {"reached", t_err <= c_err}}},
                         {"cycles_fixed_cost_taken_out", {{"cpu_s", fixed_cpu}, {"wall_s", fixed_wall}}},
                         {"speedup_cpu", (adaptive_cpu - fixed_cpu) / t.cpu},
                         {"speedup_wall", (adaptive_wall - fixed_wall) / t.wall}};
    }
  }
  std::cout << out.dump(2) << "\n";
  if (!markdown.empty()) {
    std::ofstream md(markdown, std::ios::app);
    char buf[2048];
    md << "| | spp | wall s | CPU s | samples/s (wall) | samples/s (CPU) | RMSE vs reference | RMSE vs reference, masked |\n"
          "|---|---:|---:|---:|---:|---:|---:|---:|\n";
    std::snprintf(buf, sizeof buf, "| Cycles (Blender 3.4), its fixed cost out | %d | %.3f | %.3f | %.3g | %.3g | %.4g | %.4g |\n",
                  spp, render_wall, render_cpu, c_sps_wall, c_sps_cpu, rmse(cycles, ref.image), rmse(cycles, ref.image, mask));
    md << buf;
    std::snprintf(buf, sizeof buf, "| Tessera | %d | %.3f | %.3f | %.3g | %.3g | %.4g | %.4g |\n", spp, same.wall,
                  same.cpu, t_sps_wall, t_sps_cpu, rmse(same.image, ref.image), rmse(same.image, ref.image, mask));
    md << buf;
    std::snprintf(buf, sizeof buf,
                  "\nReference: Tessera at %d spp. Mask (models agree): %.1f%% of the pixels. Cycles' mean level / the "
                  "reference's, masked: %.3f. RMSE between the two at %d spp: %.4g (masked %.4g). Throughput Tessera / "
                  "Cycles: %.2fx wall, %.2fx CPU. Cycles' fixed cost (scene synchronization, BVH, EXR write), %s: "
                  "%.3f s wall, %.3f s CPU, from its %.3f s and %.3f s (its own metadata: synchronization %.2f s, "
                  "render %.2f s, wall); with it counted as rendering the ratio would be %.2fx CPU. CPU: %s; %s.\n",
                  ref_spp, 100.0 * double(kept) / px, mean(cycles, mask) / mean(ref.image, mask), spp,
                  rmse(cycles, same.image), rmse(cycles, same.image, mask), t_sps_wall / c_sps_wall, t_sps_cpu / c_sps_cpu,
                  fitted ? "taken out" : "NOT taken out (its 1-spp times did not fit: this ratio flatters Tessera)",
                  fixed_wall, fixed_cpu, cycles_wall, cycles_cpu, own_sync, own_render, t_sps_cpu * cycles_cpu / (px * spp),
                  cpu_model().c_str(), embree_isa().c_str());
    md << buf;
    if (out.contains("references")) {
      std::snprintf(buf, sizeof buf,
                    "Both at %d spp (where the models differ, noise apart): RMSE %.4g, masked %.4g; Cycles' mean level / "
                    "Tessera's, masked: %.3f.\n",
                    ref_spp, out["references"]["rmse"].get<double>(), out["references"]["rmse_masked"].get<double>(),
                    out["references"]["mean_ratio_masked"].get<double>());
      md << buf;
    }
    if (out.contains("adaptive")) {
      const auto& a = out["adaptive"];
      std::snprintf(buf, sizeof buf,
                    "\nTime to equal error, each against its own %d-spp reference (whose own noise is in both "
                    "errors): Cycles' adaptive sampling (noise threshold %.3g, at most %d spp) %.3f CPU s, its fixed cost "
                    "out, at RMSE %.4g; "
                    "Tessera `--target-rmse %.3g` %.3f CPU s at RMSE %.4g (%s): **%.2fx** (CPU), %.2fx (wall).\n",
                    ref_spp, adaptive_threshold, adaptive_max_spp, adaptive_cpu - fixed_cpu,
                    a["cycles"]["rmse_vs_own_reference"].get<double>(),
                    a["tessera"]["target_rmse"].get<double>(), a["tessera"]["cpu_s"].get<double>(),
                    a["tessera"]["rmse_vs_own_reference"].get<double>(),
                    a["tessera"]["reached"].get<bool>() ? "reached" : "NOT reached", a["speedup_cpu"].get<double>(),
                    a["speedup_wall"].get<double>());
      md << buf;
    }
    if (out.contains("bound")) {
      const auto& b = out["bound"];
      std::snprintf(buf, sizeof buf,
                    "\nThe bound: bare Embree answers this frame's %.0f queries (%.2f a sample) in %.4f CPU s "
                    "(`ray_ceiling`, one thread, robust triangles, best packet width), against Cycles' %.4f: no "
                    "Tessera render with these rays can pass **%.2fx** Cycles' samples per CPU-second. %.1fx needs "
                    "the whole frame within %.2fx its queries' time, a ray-ceiling ratio of **%.2f**; it is %.2f "
                    "now.\n",
                    b["rays"].get<double>(), b["rays_per_sample"].get<double>(), b["bare_query_cpu_s"].get<double>(),
                    render_cpu, b["max_throughput_ratio_cpu"].get<double>(), goal,
                    1.0 / b["needed_ceiling_ratio"].get<double>(), b["needed_ceiling_ratio"].get<double>(),
                    b["ceiling_ratio_now"].get<double>());
      md << buf;
    }
  }
  return 0;
}

// SPDX-License-Identifier: Apache-2.0
// Ray throughput against the ceiling (docs/performance.md, "Ray throughput against the ceiling").
// Records the exact Embree queries the renderer makes for one frame (render/ray_log.h), replays
// them with bare Embree calls on the same RTCScene (same geometry, same user-geometry callbacks for
// spheres and watertight triangles, no shading, no sampling; --triangles picks the triangle test):
// single rays, and 8-/16-wide packets. Reports the renderer's own Mrays/s (the whole render:
// sampling, shading, accumulation) as a ratio of each, and of the ceiling that the throughput goal
// (at least 0.5 of it for primary + shadow rays on the bunny and the armadillo, 0.3 on Whitted) is
// read against: the same rays, in the faster of 8- and 16-wide packets, on the same scene built
// with Embree's own robust triangles. One thread everywhere, best of --reps, timed in thread CPU
// time. Prints JSON on stdout; appends a markdown table to --markdown. Asserts nothing about time.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "render/embree_device.h"
#include "render/ray_log.h"
#include "render/render_scene_embree.h"
#include "render/tile_renderer.h"
#include "scene/scene_parser.h"
#include "tile/tile_grid.h"

namespace fs = std::filesystem;
using namespace tessera;

namespace {

// Thread CPU time, not wall time: everything here runs on one thread, and the machine may be
// shared, so CPU time is what the work costs even when other processes take the core away.
struct Clock {
  using time_point = double;
  static double now() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
  }
};
double since(double t0) { return Clock::now() - t0; }

struct Replay {
  std::vector<RTCRay> rays;      // ray.id = index into `from`
  std::vector<PrimRef> from;
  std::vector<uint8_t> occluded;  // 1: occlusion query (shadow ray), 0: closest hit
};

// The logical rays of the log (camera, secondary, shadow; not the old glass-walk steps), in the
// order given. Shadow rays are replayed as pure visibility against opaque geometry.
Replay make_replay(const std::vector<LoggedRay>& log) {
  Replay r;
  for (const LoggedRay& l : log) {
    if (l.kind == LoggedRay::Kind::kGlassWalk) continue;
    RTCRay ray = l.ray;
    ray.id = uint32_t(r.from.size());
    const bool occ = l.kind == LoggedRay::Kind::kShadow;
    if (occ) ray.mask = RenderScene::kOpaqueMask;
    r.rays.push_back(ray);
    r.from.push_back(l.from);
    r.occluded.push_back(occ ? 1 : 0);
  }
  return r;
}

double trace_single(const RenderScene& rs, const Replay& r, uint64_t* hits) {
  RenderScene::TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = &rs;
  RTCScene scene = rs.embree_scene();
  uint64_t h = 0;
  const auto t0 = Clock::now();
  for (size_t i = 0; i < r.rays.size(); ++i) {
    ctx.from = r.from[i];
    if (r.occluded[i]) {
      RTCRay ray = r.rays[i];
      rtcOccluded1(scene, &ctx.rtc, &ray);
      h += ray.tfar < 0.0f;
    } else {
      RTCRayHit rh;
      rh.ray = r.rays[i];
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &ctx.rtc, &rh);
      h += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
  }
  const double s = since(t0);
  *hits = h;
  return s;
}

// Packets of W lanes. Coherence: within each block of 4096 consecutive rays (a few pixels' worth
// of one tile) rays are grouped by query type and then by direction octant, stably, as a
// packet tracer sorting a tile's rays would do.
template <int W>
struct Packets {
  struct alignas(64) Hit { RTCRayHitNt<W> rh; int valid[W]; };
  struct alignas(64) Occ { RTCRayNt<W> r; int valid[W]; };
  std::vector<Hit> hit;
  std::vector<Occ> occ;
};

template <typename P>
void set_lane(P* p, int lane, const RTCRay& r) {
  p->org_x[lane] = r.org_x; p->org_y[lane] = r.org_y; p->org_z[lane] = r.org_z;
  p->dir_x[lane] = r.dir_x; p->dir_y[lane] = r.dir_y; p->dir_z[lane] = r.dir_z;
  p->tnear[lane] = r.tnear; p->tfar[lane] = r.tfar; p->time[lane] = 0.0f;
  p->mask[lane] = r.mask; p->id[lane] = r.id; p->flags[lane] = 0;
}

template <int W>
Packets<W> make_packets(const Replay& r) {
  Packets<W> out;
  const size_t n = r.rays.size();
  std::vector<uint32_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
  auto key = [&](uint32_t i) {
    const RTCRay& ray = r.rays[i];
    return int(r.occluded[i]) * 8 + int(ray.dir_x < 0) * 4 + int(ray.dir_y < 0) * 2 + int(ray.dir_z < 0);
  };
  for (size_t b = 0; b < n; b += 4096) {
    std::stable_sort(order.begin() + long(b), order.begin() + long(std::min(n, b + 4096)),
                     [&](uint32_t a, uint32_t c) { return key(a) < key(c); });
  }
  size_t i = 0;
  while (i < n) {
    const bool occ = r.occluded[order[i]];
    if (occ) {
      typename Packets<W>::Occ p{};
      for (int l = 0; l < W; ++l) p.valid[l] = 0;
      int lane = 0;
      for (; lane < W && i < n && r.occluded[order[i]]; ++lane, ++i) {
        set_lane(&p.r, lane, r.rays[order[i]]);
        p.valid[lane] = -1;
      }
      out.occ.push_back(p);
    } else {
      typename Packets<W>::Hit p{};
      for (int l = 0; l < W; ++l) p.valid[l] = 0;
      int lane = 0;
      for (; lane < W && i < n && !r.occluded[order[i]]; ++lane, ++i) {
        set_lane(&p.rh.ray, lane, r.rays[order[i]]);
        p.rh.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
        p.rh.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
        p.valid[lane] = -1;
      }
      out.hit.push_back(p);
    }
  }
  return out;
}

template <int W>
double trace_packets(const RenderScene& rs, const Replay& r, Packets<W> p, uint64_t* hits) {
  RenderScene::TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = &rs;
  ctx.from_by_id = r.from.data();
  RTCScene scene = rs.embree_scene();
  const auto t0 = Clock::now();
  for (auto& q : p.hit) {
    if constexpr (W == 8) rtcIntersect8(q.valid, scene, &ctx.rtc, reinterpret_cast<RTCRayHit8*>(&q.rh));
    else rtcIntersect16(q.valid, scene, &ctx.rtc, reinterpret_cast<RTCRayHit16*>(&q.rh));
  }
  for (auto& q : p.occ) {
    if constexpr (W == 8) rtcOccluded8(q.valid, scene, &ctx.rtc, reinterpret_cast<RTCRay8*>(&q.r));
    else rtcOccluded16(q.valid, scene, &ctx.rtc, reinterpret_cast<RTCRay16*>(&q.r));
  }
  const double s = since(t0);
  uint64_t h = 0;
  for (auto& q : p.hit) {
    for (int l = 0; l < W; ++l) h += q.valid[l] && q.rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
  }
  for (auto& q : p.occ) {
    for (int l = 0; l < W; ++l) h += q.valid[l] && q.r.tfar[l] < 0.0f;
  }
  *hits = h;
  return s;
}

struct Ceiling {
  double single_s = 1e30, p8_s = 1e30, p16_s = -1;  // p16_s < 0: 16-wide packets not supported
  uint64_t hits1 = 0, hits8 = 0, hits16 = 0;
  // Mrays/s of the faster packet width for n rays.
  double best_packet_mrays(double n) const { return n / std::min(p8_s, p16_s > 0 ? p16_s : 1e30) / 1e6; }
};

Ceiling measure_ceiling(const RenderScene& rs, const Replay& replay, int reps) {
  Ceiling c;
  for (int i = 0; i < reps; ++i) c.single_s = std::min(c.single_s, trace_single(rs, replay, &c.hits1));
  {
    const auto packets = make_packets<8>(replay);
    for (int i = 0; i < reps; ++i) c.p8_s = std::min(c.p8_s, trace_packets<8>(rs, replay, packets, &c.hits8));
  }
  const auto packets = make_packets<16>(replay);
  uint64_t h = 0;
  const double s = trace_packets<16>(rs, replay, packets, &h);
  try {
    check_embree("rtcIntersect16");
  } catch (const EmbreeError&) {
    return c;  // not supported by this build/ISA
  }
  c.p16_s = s;
  c.hits16 = h;
  for (int i = 1; i < reps; ++i) c.p16_s = std::min(c.p16_s, trace_packets<16>(rs, replay, packets, &c.hits16));
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Renderer Mrays/s against bare Embree on the renderer's own rays"};
  std::string scene_path, markdown;
  int width = 320, height = 180, spp = 4, reps = 3;
  std::optional<int> depth;
  app.add_option("--scene", scene_path, "Scene JSON")->required()->check(CLI::ExistingFile);
  app.add_option("--width", width)->check(CLI::Range(1, 16384));
  app.add_option("--height", height)->check(CLI::Range(1, 16384));
  app.add_option("--spp", spp)->check(CLI::Range(1, 65536));
  app.add_option("--max-depth", depth, "0: primary and shadow rays only (default: the scene's)")
      ->check(CLI::Range(0, 64));
  app.add_option("--reps", reps, "Repetitions; the best time counts")->check(CLI::Range(1, 100));
  app.add_option("--markdown", markdown, "Append a markdown table row to this file");
  double goal = 0;
  app.add_option("--goal", goal, "Goal for the renderer / robust packet ceiling ratio (markdown column; 0: none)");
  TriangleTest triangles = TriangleTest::kWatertight;
  const std::map<std::string, TriangleTest> triangle_tests = {
      {triangle_test_name(TriangleTest::kWatertight), TriangleTest::kWatertight},
      {triangle_test_name(TriangleTest::kEmbreeRobust), TriangleTest::kEmbreeRobust},
      {triangle_test_name(TriangleTest::kEmbreeFast), TriangleTest::kEmbreeFast}};
  app.add_option("--triangles", triangles, "Triangle test (docs/accuracy.md, case 4)")
      ->transform(CLI::CheckedTransformer(triangle_tests));
  SphereSearch spheres = SphereSearch::kScanSmall;
  const std::map<std::string, SphereSearch> sphere_searches = {
      {sphere_search_name(SphereSearch::kScanSmall), SphereSearch::kScanSmall},
      {sphere_search_name(SphereSearch::kEmbree), SphereSearch::kEmbree}};
  app.add_option("--spheres", spheres, "How the renderer finds spheres (render/render_options.h; the ceiling is Embree's)")
      ->transform(CLI::CheckedTransformer(sphere_searches));
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  Scene scene;
  try {
    scene = load_scene(scene_path);
  } catch (const std::exception& e) {
    std::cerr << "ray_ceiling: " << e.what() << "\n";
    return 2;
  }
  scene.image.width = width;
  scene.image.height = height;
  scene.image.spp = spp;
  if (depth) scene.image.max_depth = *depth;
  const RenderScene rs(scene, 0, {triangles, spheres});
  const std::vector<TileRect> tiles = TileGrid(width, height, 32).rects();

  // 1. The renderer, one thread, whole frame (sampling + tracing + shading + accumulation).
  double render_s = 1e30;
  RayCounts counts;
  for (int i = 0; i < reps; ++i) {
    RayCounts c;
    const auto t0 = Clock::now();
    for (const TileRect& t : tiles) c += render_tile(rs, t).rays;
    render_s = std::min(render_s, since(t0));
    counts = c;
  }
  // 2. The same frame once more with the log on: the rays it traces.
  RayLog log;
  thread_ray_log() = &log;
  for (const TileRect& t : tiles) render_tile(rs, t);
  thread_ray_log() = nullptr;
  const Replay replay = make_replay(log.rays);
  const uint64_t logical = counts.total();
  if (replay.rays.size() != logical) {
    std::cerr << "ray_ceiling: logged " << replay.rays.size() << " rays but the renderer counted " << logical << "\n";
    return 1;
  }
  uint64_t glass_walk = 0;
  for (const LoggedRay& l : log.rays) glass_walk += l.kind == LoggedRay::Kind::kGlassWalk;

  // 3. Bare Embree on the renderer's scene (its triangle test), and the ceiling the throughput goal
  // is read against: the same rays on the same scene with Embree's own robust triangles (spheres
  // stay user geometry: Embree has no double-precision sphere).
  const Ceiling ours = measure_ceiling(rs, replay, reps);
  const bool has_triangles = rs.triangle_count() > 0;
  std::optional<RenderScene> robust_scene;
  if (has_triangles && triangles != TriangleTest::kEmbreeRobust) robust_scene.emplace(scene, 0, RenderOptions{TriangleTest::kEmbreeRobust});
  const Ceiling robust = robust_scene ? measure_ceiling(*robust_scene, replay, reps) : ours;
  const double single_s = ours.single_s, p8_s = ours.p8_s, p16_s = ours.p16_s;
  const uint64_t hits1 = ours.hits1, hits8 = ours.hits8, hits16 = ours.hits16;
  const double n = double(logical);
  const double r_mrays = n / render_s / 1e6, s_mrays = n / single_s / 1e6, p8_mrays = n / p8_s / 1e6;
  const double p16_mrays = p16_s > 0 ? n / p16_s / 1e6 : 0;
  const std::string name = fs::path(scene_path).stem().string();
  const double robust_mrays = robust.best_packet_mrays(n);

  nlohmann::json out = {{"scene", name},
                        {"width", width},
                        {"height", height},
                        {"spp", spp},
                        {"max_depth", scene.image.max_depth},
                        {"threads", 1},
                        {"triangles", triangle_test_name(triangles)},
                        {"spheres", sphere_search_name(spheres)},
                        {"renderer", embree_isa()},
                        {"rays", {{"camera", counts.camera}, {"shadow", counts.shadow}, {"secondary", counts.secondary},
                                  {"extra_glass_walk_queries", glass_walk}}},
                        {"hits", {{"single", hits1}, {"packet8", hits8}, {"packet16", hits16}}},
                        {"seconds", {{"renderer", render_s}, {"single", single_s}, {"packet8", p8_s}, {"packet16", p16_s}}},
                        {"mrays_per_s", {{"renderer", r_mrays}, {"single", s_mrays}, {"packet8", p8_mrays},
                                         {"packet16", p16_mrays}}},
                        {"ratio", {{"single", r_mrays / s_mrays}, {"packet8", r_mrays / p8_mrays},
                                   {"packet16", p16_mrays > 0 ? r_mrays / p16_mrays : 0.0}}},
                        {"robust_ceiling", {{"triangles", robust_scene ? "embree-robust" : triangle_test_name(triangles)},
                                            {"seconds", {{"single", robust.single_s}, {"packet8", robust.p8_s},
                                                         {"packet16", robust.p16_s}}},
                                            {"hits", {{"single", robust.hits1}, {"packet8", robust.hits8},
                                                      {"packet16", robust.hits16}}},
                                            {"best_packet_mrays_per_s", robust_mrays},
                                            {"ratio", r_mrays / robust_mrays}}}};
  std::cout << out.dump(2) << "\n";
  if (!markdown.empty()) {
    std::ofstream md(markdown, std::ios::app);
    char buf[512];
    const double ratio = r_mrays / robust_mrays;
    std::snprintf(buf, sizeof buf,
                  "| %s | %dx%d, %d spp, depth %d | %.2fM | %.2f | %.2f | %.2f | %s | %.2f | %.2f / %.2f / %s | **%.2f** | %s |\n",
                  name.c_str(), width, height, spp, scene.image.max_depth, n / 1e6, r_mrays, s_mrays, p8_mrays,
                  p16_mrays > 0 ? std::to_string(p16_mrays).substr(0, 5).c_str() : "n/a", robust_mrays,
                  r_mrays / s_mrays, r_mrays / p8_mrays,
                  p16_mrays > 0 ? std::to_string(r_mrays / p16_mrays).substr(0, 4).c_str() : "n/a", ratio,
                  goal <= 0 ? "" : ratio >= goal ? ("met (>= " + std::to_string(goal).substr(0, 3) + ")").c_str()
                                                 : ("not met (>= " + std::to_string(goal).substr(0, 3) + ")").c_str());
    md << buf;
  }
  return 0;
}

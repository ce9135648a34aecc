// SPDX-License-Identifier: Apache-2.0
// Rays as a service, measured (results in docs/rays.md). For the bunny and a large
// mesh (the armadillo, 346k triangles), coherent (camera grid) and incoherent (random) rays:
//   bare Embree  rtcIntersect1 on the same RTCScene, same user-geometry callbacks, render-space
//                rays prepared beforehand: the traversal ceiling (the goal's denominator)
//   bare Embree, application: the same, with the Embree rays made from the world rays and the
//                raw answers copied out inside the timing: what the least Embree program pays
//   in-process   RayTracer::nearest (lib/rays) in batches of 1, 64, 4096, 65536 world-space rays
//   gRPC unary   RayService.Trace over loopback TCP, one batch per call, request encoding and
//                answer decoding included
//   gRPC stream  RayService.TraceStream, every batch in flight at once
//   gRPC stream, t only: the same with the field mask {T}: the answers carry hit and t alone
//                (5 bytes a ray instead of 73), what a lidar-like client asks for
// plus the latency (p50, p99) of single-ray Trace calls. One tracing thread everywhere (the
// service runs with --threads 1), best of --reps. Two clocks: wall time, and the process's CPU
// time (every thread: client, gRPC, server; user + system): on a shared machine the CPU time is
// what the work costs even while other processes take the cores away, so the goal ratios are
// computed from it; the wall-clock rates are in the JSON too.
// Prints JSON on stdout; appends a markdown table to --markdown. Asserts nothing about time.
#include <grpcpp/grpcpp.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "../bench_host.h"
#include "large_buffers.h"
#include "ray_service.h"
#include "rays/ray_codec.h"
#include "render/embree_device.h"
#include "render/render_scene_embree.h"
#include "scene/scene_parser.h"

namespace fs = std::filesystem;
using namespace tessera;
using namespace tessera::rays;
using namespace tessera::rayserver;  // the ray server (rays/), measured in this process
using Clock = std::chrono::steady_clock;
using bench::cpu_model;
using bench::process_cpu_seconds;

namespace {

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Rays per second of wall time and of process CPU time.
struct Rate {
  double wall = 0, cpu = 0;
};

class Stopwatch {
 public:
  Stopwatch() : wall_(Clock::now()), cpu_(process_cpu_seconds()) {}
  Rate rate(double rays) const {
    return {rays / seconds_since(wall_), rays / std::max(1e-9, process_cpu_seconds() - cpu_)};
  }

 private:
  Clock::time_point wall_;
  double cpu_;
};

// Camera rays through a side x side grid of the scene's own camera, in pixel order.
std::vector<WorldRay> coherent_rays(const RenderScene& rs, int side) {
  std::vector<WorldRay> rays;
  const auto& cam = rs.camera();
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      const float u = (float(x) + 0.5f) / float(side), v = (float(y) + 0.5f) / float(side);
      rays.push_back({rs.origin(), Vec3d(normalize(cam.p0 + cam.du * u + cam.dv * v))});
    }
  }
  return rays;
}

// From random points on a sphere around the subject towards random points near its centre:
// every ray takes its own path through the BVH.
std::vector<WorldRay> incoherent_rays(const Scene& scene, size_t n) {
  const Vec3d c = scene.camera.look_at;
  const double r = length(scene.camera.position - c);
  std::mt19937_64 rng(18);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  std::vector<WorldRay> rays;
  for (size_t i = 0; i < n; ++i) {
    const Vec3d o = c + normalize(Vec3d(g(rng), g(rng), g(rng))) * (1.5 * r);
    const Vec3d target = c + Vec3d(u(rng), u(rng), u(rng)) * r;
    rays.push_back({o, normalize(target - o)});
  }
  return rays;
}

// The same rays as Embree queries: render space, and tfar clipped at the nearest infinite plane
// (the renderer intersects planes itself and asks Embree only for what lies before them). The
// preparation is not timed: this is the ceiling a service could approach.
std::vector<RTCRayHit> embree_rays(const Scene& scene, const RenderScene& rs, const std::vector<WorldRay>& world) {
  std::vector<RTCRayHit> rays(world.size());
  for (size_t i = 0; i < world.size(); ++i) {
    const Vec3f o(world[i].o - rs.origin()), d(world[i].d);
    float tfar = std::numeric_limits<float>::infinity();
    for (const SceneObject& obj : scene.objects) {  // untransformed planes (those of these scenes)
      if (obj.type != SceneObject::Type::kPlane) continue;
      const double t = dot(obj.point - world[i].o, obj.normal) / dot(world[i].d, obj.normal);
      if (t > 0 && t < tfar) tfar = float(t);
    }
    RTCRayHit& rh = rays[i];
    rh.ray = {o.x, o.y, o.z, 0.0f, d.x, d.y, d.z, 0.0f, tfar, 0xFFFFFFFFu, 0, 0};
  }
  return rays;
}

// Traces prepared rays (their tfar and hits are overwritten: pass a fresh copy each time).
Rate bare_embree(const RenderScene& rs, std::vector<RTCRayHit>& rays) {
  RenderScene::TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = &rs;
  const Stopwatch watch;
  for (RTCRayHit& rh : rays) {
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(rs.embree_scene(), &ctx.rtc, &rh);
  }
  return watch.rate(double(rays.size()));
}

// What the least Embree program does for the same queries, timed whole: each world ray made an
// Embree ray (minus the eye, rounded to float; tfar at the nearest plane, from `prepared`, since
// Embree has no infinite planes), traced, and its raw answer (t, unnormalized normal, u, v,
// geometry and primitive id) copied out. No double precision, no hit point, no names.
struct RawHit {
  float t, ng[3], u, v;
  uint32_t geom, prim;
};
Rate bare_embree_application(const RenderScene& rs, const std::vector<WorldRay>& world,
                             const std::vector<RTCRayHit>& prepared, std::vector<RawHit>* out) {
  RenderScene::TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = &rs;
  out->resize(world.size());
  const Stopwatch watch;
  for (size_t i = 0; i < world.size(); ++i) {
    const Vec3f o(world[i].o - rs.origin()), d(world[i].d);
    RTCRayHit rh;
    rh.ray = {o.x, o.y, o.z, 0.0f, d.x, d.y, d.z, 0.0f, prepared[i].ray.tfar, 0xFFFFFFFFu, 0, 0};
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(rs.embree_scene(), &ctx.rtc, &rh);
    (*out)[i] = {rh.ray.tfar, {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z}, rh.hit.u, rh.hit.v, rh.hit.geomID, rh.hit.primID};
  }
  return watch.rate(double(world.size()));
}

// Bare Embree with packets of K consecutive prepared rays (rtcIntersect4/8/16, the same callbacks,
// which take the K lanes in one call): would tracing rays K at a time beat one at a time? On the
// same rays it does not (docs/rays.md): the callbacks' per-ray work is the same, and incoherent
// packets traverse nodes that only some of their lanes need.
template <int K, class RH>
Rate bare_embree_packets(const RenderScene& rs, const std::vector<RTCRayHit>& rays,
                         void (*intersect)(const int*, RTCScene, RTCIntersectContext*, RH*)) {
  RenderScene::TraceContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.scene = &rs;
  alignas(64) RH rh;
  alignas(64) int valid[K];
  const Stopwatch watch;
  for (size_t b = 0; b < rays.size(); b += K) {
    for (int i = 0; i < K; ++i) {
      valid[i] = b + size_t(i) < rays.size() ? -1 : 0;
      if (!valid[i]) continue;
      const RTCRay& r = rays[b + size_t(i)].ray;
      rh.ray.org_x[i] = r.org_x, rh.ray.org_y[i] = r.org_y, rh.ray.org_z[i] = r.org_z;
      rh.ray.dir_x[i] = r.dir_x, rh.ray.dir_y[i] = r.dir_y, rh.ray.dir_z[i] = r.dir_z;
      rh.ray.tnear[i] = 0.0f, rh.ray.tfar[i] = r.tfar, rh.ray.time[i] = 0.0f;
      rh.ray.mask[i] = 0xFFFFFFFFu, rh.ray.id[i] = 0, rh.ray.flags[i] = 0;
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    intersect(valid, rs.embree_scene(), &ctx.rtc, &rh);
  }
  return watch.rate(double(rays.size()));
}

Rate bare_embree(const Scene& scene, const RenderScene& rs, const std::vector<WorldRay>& world) {
  std::vector<RTCRayHit> rays = embree_rays(scene, rs, world);
  return bare_embree(rs, rays);
}

Rate in_process(const RayTracer& tracer, const std::vector<WorldRay>& rays, size_t batch, bool occlusion = false) {
  std::vector<WorldHit> hits(rays.size());
  const Stopwatch watch;
  for (size_t b = 0; b < rays.size(); b += batch) {
    const size_t n = std::min(batch, rays.size() - b);
    if (occlusion) tracer.occluded(rays.data() + b, n, hits.data() + b);
    else tracer.nearest(rays.data() + b, n, hits.data() + b);
  }
  return watch.rate(double(rays.size()));
}

// The field mask of the t-only measurements: hit and t come back, nothing else.
constexpr HitFields kTOnly = HitFields().with(HitField::kT);

v1::TraceRequest make_request(const std::vector<WorldRay>& rays, size_t begin, size_t end,
                              HitFields fields = HitFields::all()) {
  v1::TraceRequest req;
  req.mutable_scene()->set_bundle_sha256(std::string(64, '0'));
  encode_fields(fields, &req);
  encode_rays({rays.begin() + long(begin), rays.begin() + long(end)}, {}, &req);
  return req;
}

// Unary calls of `batch` rays over the first `total` rays; encode and decode included.
Rate grpc_unary(v1::RayService::Stub& stub, const std::vector<WorldRay>& rays, size_t batch, size_t total) {
  const Stopwatch watch;
  for (size_t b = 0; b < total; b += batch) {
    const size_t e = std::min(total, b + batch);
    grpc::ClientContext ctx;
    v1::TraceResponse resp;
    if (!stub.Trace(&ctx, make_request(rays, b, e), &resp).ok()) throw std::runtime_error("Trace failed");
    decode_hits(resp, e - b, false);
  }
  return watch.rate(double(total));
}

Rate grpc_stream(v1::RayService::Stub& stub, const std::vector<WorldRay>& rays, size_t batch,
                 HitFields fields = HitFields::all()) {
  const Stopwatch watch;
  grpc::ClientContext ctx;
  auto stream = stub.TraceStream(&ctx);
  std::thread writer([&] {
    for (size_t b = 0; b < rays.size(); b += batch) {
      if (!stream->Write(make_request(rays, b, std::min(rays.size(), b + batch), fields))) break;
    }
    stream->WritesDone();
  });
  v1::TraceResponse resp;
  for (size_t b = 0; b < rays.size() && stream->Read(&resp); b += batch) {
    decode_hits(resp, std::min(rays.size(), b + batch) - b, false, fields);
  }
  writer.join();
  if (!stream->Finish().ok()) throw std::runtime_error("TraceStream failed");
  return watch.rate(double(rays.size()));
}

std::pair<double, double> latency_us(v1::RayService::Stub& stub, const std::vector<WorldRay>& rays, size_t calls) {
  std::vector<double> us;
  for (size_t i = 0; i < calls; ++i) {
    const size_t k = i % rays.size();
    const v1::TraceRequest req = make_request(rays, k, k + 1);
    const auto t0 = Clock::now();
    grpc::ClientContext ctx;
    v1::TraceResponse resp;
    if (!stub.Trace(&ctx, req, &resp).ok()) throw std::runtime_error("Trace failed");
    us.push_back(seconds_since(t0) * 1e6);
  }
  std::sort(us.begin(), us.end());
  return {us[us.size() / 2], us[std::min(us.size() - 1, us.size() * 99 / 100)]};
}

template <class F>
Rate best_of(int reps, F f) {
  Rate best;
  for (int i = 0; i < reps; ++i) {
    const Rate r = f();
    best = {std::max(best.wall, r.wall), std::max(best.cpu, r.cpu)};
  }
  return best;
}

nlohmann::json to_json(const Rate& r) { return {{"wall", r.wall}, {"cpu", r.cpu}}; }

}  // namespace

int main(int argc, char** argv) {
  keep_large_buffers();  // as tessera-rays does: the service here runs in this process
  bool smoke = false;
  int reps = 7;  // best of: filters out preemption on a shared machine
  std::string markdown;
  std::vector<std::string> scenes = {"bunny", "armadillo"};
  CLI::App app{"rays_bench: the ray service against in-process tracing and bare Embree"};
  app.add_flag("--smoke", smoke, "A few thousand rays, one rep, the bunny only: checks that it runs");
  app.add_option("--reps", reps, "Best of this many runs")->check(CLI::Range(1, 100));
  app.add_option("--scenes", scenes, "bunny, armadillo")->delimiter(',');
  app.add_option("--markdown", markdown, "Append a markdown table to this file");
  std::string profile;
  double profile_seconds = 5;
  app.add_option("--profile", profile,
                 "Only run this for --profile-seconds: in-process, bare, occlusion, grpc, grpc-t-only (for a profiler: incoherent rays of the first scene), or ratio (in-process against bare Embree, the gRPC streams against in-process, and bare Embree in packets of 4, 8 and 16, alternated, fastest of each, for every scene)");
  app.add_option("--profile-seconds", profile_seconds)->check(CLI::Range(0.1, 600.0));
  CLI11_PARSE(app, argc, argv);
  if (smoke) {
    reps = 1;
    scenes = {"bunny"};
  }
  const std::map<std::string, std::string> files = {{"bunny", "scenes/bunny.json"},
                                                    {"armadillo", "bench/rays/armadillo.json"}};
  const int side = smoke ? 64 : 256;  // 65,536 rays per set, 4,096 for the smoke run
  const std::vector<size_t> batches = smoke ? std::vector<size_t>{1, 64, 4096} : std::vector<size_t>{1, 64, 4096, 65536};

  nlohmann::json out;
  out["cpu"] = cpu_model();
  out["cores"] = std::thread::hardware_concurrency();
  out["embree_isa"] = embree_isa();
  out["tracing_threads"] = 1;
  std::string md = "\n| scene | rays | bare Embree | in-process b=1 | 64 | 4096 | 65536 | gRPC unary b=1 | 64 | 4096 | "
                   "65536 | stream 4096 | 65536 | in-proc/Embree cpu (wall) | gRPC/in-proc, worst b≥4096, cpu (wall) | "
                   "p50 µs | p99 µs | stream t-only 4096 | 65536 | t-only/in-proc, worst b≥4096, cpu (wall) |\n"
                   "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const std::string& name : scenes) {
    if (!files.count(name)) {
      std::cerr << "rays_bench: unknown scene " << name << "\n";
      return 2;
    }
    const std::string path = std::string(TESSERA_SOURCE_DIR) + "/" + files.at(name);
    auto scene = std::make_shared<const Scene>(load_scene(path));
    auto rs = std::make_shared<const RenderScene>(*scene, 0);
    auto tracer = std::make_shared<const RayTracer>(scene, rs);

    // The service on loopback, in this process, one tracing thread.
    RayServiceOptions options;
    options.threads = 1;
    options.max_batch_rays = 1 << 20;
    RayServiceImpl service(
        [tracer](const std::string&, int, std::shared_ptr<const RayTracer>* t) {
          *t = tracer;
          return grpc::Status::OK;
        },
        farm::Authenticator(), options);
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(&service);
    builder.SetMaxReceiveMessageSize(64 << 20);
    builder.SetMaxSendMessageSize(64 << 20);
    std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(64 << 20);
    args.SetMaxSendMessageSize(64 << 20);
    auto stub = v1::RayService::NewStub(
        grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials(), args));

    if (profile == "ratio") {
      // In-process against bare Embree, and the gRPC streams against in-process, alternated many
      // times on the same rays, fastest of each (short runs, so some land between other
      // processes' bursts on a shared machine).
      for (const bool coherent : {true, false}) {
        const std::vector<WorldRay> rays =
            coherent ? coherent_rays(*rs, side) : incoherent_rays(*scene, size_t(side) * size_t(side));
        const std::vector<RTCRayHit> prepared = embree_rays(*scene, *rs, rays);
        std::vector<WorldHit> hits(rays.size());
        std::vector<RawHit> raw;
        double bare = 0, app = 0, ip = 0, ip_cpu = 0, p4 = 0, p8 = 0, p16 = 0;
        Rate stream, stream_t;  // the gRPC streams at 4,096 rays a batch: every field, t alone
        auto keep = [](Rate* best, const Rate& r) { *best = {std::max(best->wall, r.wall), std::max(best->cpu, r.cpu)}; };
        const auto t0 = Clock::now();
        while (seconds_since(t0) < profile_seconds) {
          std::vector<RTCRayHit> work = prepared;
          bare = std::max(bare, bare_embree(*rs, work).wall);
          p4 = std::max(p4, bare_embree_packets<4>(*rs, prepared, rtcIntersect4).wall);
          p8 = std::max(p8, bare_embree_packets<8>(*rs, prepared, rtcIntersect8).wall);
          p16 = std::max(p16, bare_embree_packets<16>(*rs, prepared, rtcIntersect16).wall);
          app = std::max(app, bare_embree_application(*rs, rays, prepared, &raw).wall);
          const Stopwatch watch;
          tracer->nearest(rays.data(), rays.size(), hits.data());
          const Rate r = watch.rate(double(rays.size()));
          ip = std::max(ip, r.wall);
          ip_cpu = std::max(ip_cpu, r.cpu);
          keep(&stream, grpc_stream(*stub, rays, 4096));
          keep(&stream_t, grpc_stream(*stub, rays, 4096, kTOnly));
        }
        std::printf("%s %s: bare %.2f, bare application %.2f, in-process %.2f Mrays/s, ratio %.3f (to the application %.3f); "
                    "gRPC stream 4096 / in-process: every field %.3f CPU (%.3f wall), t only %.3f CPU (%.3f wall); "
                    "streams %.2f and %.2f Mrays per CPU-second (in-process %.2f)\n",
                    name.c_str(), coherent ? "coherent" : "incoherent", bare / 1e6, app / 1e6, ip / 1e6, ip / bare,
                    ip / app, stream.cpu / ip_cpu, stream.wall / ip, stream_t.cpu / ip_cpu, stream_t.wall / ip,
                    stream.cpu / 1e6, stream_t.cpu / 1e6, ip_cpu / 1e6);
        std::printf("  bare Embree in packets of 4, 8, 16 rays: %.2f, %.2f, %.2f Mrays/s (one at a time %.2f)\n", p4 / 1e6,
                    p8 / 1e6, p16 / 1e6, bare / 1e6);
      }
      continue;
    }
    const bool grpc_profile = profile == "grpc" || profile == "grpc-t-only";
    if (!profile.empty() && !grpc_profile) {
      const std::vector<WorldRay> rays = incoherent_rays(*scene, size_t(side) * size_t(side));
      const auto t0 = Clock::now();
      size_t loops = 0;
      while (seconds_since(t0) < profile_seconds) {
        if (profile == "bare") bare_embree(*scene, *rs, rays);
        else in_process(*tracer, rays, rays.size(), profile == "occlusion");
        ++loops;
      }
      std::printf("%s: %.1f Mrays/s\n", profile.c_str(), double(loops * rays.size()) / seconds_since(t0) / 1e6);
      return 0;
    }
    if (grpc_profile) {
      const std::vector<WorldRay> rays = incoherent_rays(*scene, size_t(side) * size_t(side));
      const HitFields fields = profile == "grpc" ? HitFields::all() : kTOnly;
      const auto t0 = Clock::now();
      size_t loops = 0;
      while (seconds_since(t0) < profile_seconds) {
        grpc_stream(*stub, rays, 4096, fields);
        ++loops;
      }
      std::printf("%s: %.1f Mrays/s\n", profile.c_str(), double(loops * rays.size()) / seconds_since(t0) / 1e6);
      return 0;
    }
    nlohmann::json js;
    js["triangles"] = rs->triangle_count();
    for (const bool coherent : {true, false}) {
      const std::vector<WorldRay> rays =
          coherent ? coherent_rays(*rs, side) : incoherent_rays(*scene, size_t(side) * size_t(side));
      nlohmann::json r;
      r["rays"] = rays.size();
      std::vector<WorldHit> hits(rays.size());
      tracer->nearest(rays.data(), rays.size(), hits.data());
      r["hit_fraction"] = double(std::count_if(hits.begin(), hits.end(), [](const WorldHit& h) { return h.hit; })) /
                          double(rays.size());
      const Rate bare = best_of(reps, [&] { return bare_embree(*scene, *rs, rays); });
      r["bare_embree_rays_per_s"] = to_json(bare);
      const std::vector<RTCRayHit> prepared = embree_rays(*scene, *rs, rays);
      std::vector<RawHit> raw;
      const Rate app = best_of(reps, [&] { return bare_embree_application(*rs, rays, prepared, &raw); });
      r["bare_embree_application_rays_per_s"] = to_json(app);
      // Line-of-sight queries (any-hit traversal) on the same rays, all in one batch.
      const Rate occ = best_of(reps, [&] { return in_process(*tracer, rays, rays.size(), true); });
      r["in_process_occlusion_rays_per_s"] = to_json(occ);
      std::map<size_t, Rate> ip, gu, gs, gt;
      double worst_cpu = 1e30, worst_wall = 1e30;  // the goal's ratio: the smallest over batches >= 4096
      double worst_t_cpu = 1e30, worst_t_wall = 1e30;  // the same for t-only streams
      for (size_t b : batches) {
        const std::string k = std::to_string(b);
        ip[b] = best_of(reps, [&] { return in_process(*tracer, rays, b); });
        // Single rays: a sample of calls is enough (and keeps the bench short).
        const size_t total = b == 1 ? std::min(rays.size(), size_t(smoke ? 300 : 3000)) : rays.size();
        gu[b] = best_of(reps, [&] { return grpc_unary(*stub, rays, b, total); });
        r["in_process_rays_per_s"][k] = to_json(ip[b]);
        r["grpc_unary_rays_per_s"][k] = to_json(gu[b]);
        if (b >= 4096) {
          gs[b] = best_of(reps, [&] { return grpc_stream(*stub, rays, b); });
          r["grpc_stream_rays_per_s"][k] = to_json(gs[b]);
          // The service's better way to deliver batches of b (one call each, or a stream of
          // them) against tracing the same batches in-process.
          const Rate ratio{std::max(gu[b].wall, gs[b].wall) / ip[b].wall, std::max(gu[b].cpu, gs[b].cpu) / ip[b].cpu};
          r["ratio_grpc_to_in_process"][k] = to_json(ratio);
          worst_cpu = std::min(worst_cpu, ratio.cpu);
          worst_wall = std::min(worst_wall, ratio.wall);
          // A stream of the same batches asking for t alone (field mask {T}).
          gt[b] = best_of(reps, [&] { return grpc_stream(*stub, rays, b, kTOnly); });
          r["grpc_stream_t_only_rays_per_s"][k] = to_json(gt[b]);
          const Rate t_ratio{gt[b].wall / ip[b].wall, gt[b].cpu / ip[b].cpu};
          r["ratio_grpc_t_only_to_in_process"][k] = to_json(t_ratio);
          worst_t_cpu = std::min(worst_t_cpu, t_ratio.cpu);
          worst_t_wall = std::min(worst_t_wall, t_ratio.wall);
        }
      }
      const auto [p50, p99] = latency_us(*stub, rays, smoke ? 300 : 3000);
      r["single_ray_latency_us"] = {{"p50", p50}, {"p99", p99}};
      // All the rays in one call against bare Embree on the same rays.
      const Rate all = ip[batches.back()];
      const Rate to_bare{all.wall / bare.wall, all.cpu / bare.cpu};
      r["ratio_in_process_to_bare_embree"] = to_json(to_bare);
      r["ratio_in_process_to_bare_embree_application"] = to_json({all.wall / app.wall, all.cpu / app.cpu});
      r["ratio_occlusion_to_nearest_in_process"] = to_json({occ.wall / all.wall, occ.cpu / all.cpu});
      r["ratio_grpc_to_in_process_batch_ge_4096"] = to_json({worst_wall, worst_cpu});
      r["ratio_grpc_t_only_to_in_process_batch_ge_4096"] = to_json({worst_t_wall, worst_t_cpu});
      js[coherent ? "coherent" : "incoherent"] = r;
      auto m = [](double x) {
        char b[32];
        std::snprintf(b, sizeof b, "%.2f", x / 1e6);
        return std::string(b);
      };
      auto at = [&](const std::map<size_t, Rate>& rates, size_t b) {
        return rates.count(b) ? m(rates.at(b).cpu) : std::string("–");
      };
      char tail[160];
      std::snprintf(tail, sizeof tail, "%.2f (%.2f) | %.2f (%.2f) | %.0f | %.0f | %s | %s | %.2f (%.2f)", to_bare.cpu,
                    to_bare.wall, worst_cpu, worst_wall, p50, p99, at(gt, 4096).c_str(), at(gt, 65536).c_str(),
                    worst_t_cpu, worst_t_wall);
      md += "| " + name + " (" + std::to_string(rs->triangle_count()) + " tris) | " +
            (coherent ? "coherent" : "incoherent") + " | " + m(bare.cpu) + " | " + at(ip, 1) + " | " + at(ip, 64) +
            " | " + at(ip, 4096) + " | " + at(ip, 65536) + " | " + at(gu, 1) + " | " + at(gu, 64) + " | " +
            at(gu, 4096) + " | " + at(gu, 65536) + " | " + at(gs, 4096) + " | " + at(gs, 65536) + " | " + tail +
            " |\n";
    }
    out["scenes"][name] = js;
    server->Shutdown();
  }
  if (profile == "ratio") return 0;
  std::cout << out.dump(2) << "\n";
  if (!markdown.empty()) {
    std::ofstream(markdown, std::ios::app) << "\nrays_bench (Mrays per CPU-second of the whole process, one tracing thread; "
                                           << out["cpu"].get<std::string>()
                                           << ", Embree " << out["embree_isa"].get<std::string>() << ")\n"
                                           << md;
  }
  return 0;
}

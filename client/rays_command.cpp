// SPDX-License-Identifier: Apache-2.0
// `tessera rays SCENE --in rays.csv --out hits.csv`: nearest-hit or occlusion queries for a file
// of rays, in-process (lib/rays, the renderer's intersection code), or on a tessera-rays service:
// the one named with --server, or with --coordinator alone one the coordinator lists (the scene
// bundle is uploaded to the coordinator first). Same answers either way, bit for bit. Exit codes:
// 0 done, 1 failure (network, I/O, no ray server), 2 bad input.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <random>
#include <thread>

#include "bundle_upload.h"
#include "commands.h"
#include "farm/bundle.h"
#include "farm/channel.h"
#include "farm_client.h"
#include "farm_command.h"
#include "rays/hit_fields.h"
#include "rays/parallel_trace.h"
#include "rays/ray_codec.h"
#include "rays/ray_csv.h"
#include "rays/ray_npy.h"
#include "scene/scene_parser.h"
#include "tessera/v1/ray_service.grpc.pb.h"

namespace tessera::cli {

namespace v1 = tessera::v1;
using rays::HitFields;
using rays::HitTable;
using rays::RayTable;

namespace {

struct RaysArgs {
  std::string scene, in, out, server, coordinator;
  SecurityFlags security;
  int frame = 0;
  bool occlusion = false;
  std::optional<std::string> fields;  // --fields as given; none: every field
  int batch = 65536;
  int timeout = 3600;  // seconds for the whole stream of batches
};

bool is_npy(const std::string& path) { return path.size() >= 4 && path.compare(path.size() - 4, 4, ".npy") == 0; }

RayTable read_rays(const std::string& path) {
  try {
    if (is_npy(path)) return rays::read_rays_npy(path);
    std::ifstream in(path);
    if (!in) throw CommandError{kExitBadInput, path + ": cannot open"};
    return rays::read_rays_csv(in, path);
  } catch (const rays::RaysError& e) {
    throw CommandError{kExitBadInput, e.what()};
  }
}

void write_hits(const std::string& path, const RayTable& rays, const HitTable& hits) {
  try {
    if (is_npy(path)) return rays::write_hits_npy(path, rays, hits);
    std::ofstream out(path);
    rays::write_hits_csv(out, rays, hits);
    out.close();
    if (!out) throw CommandError{kExitFailure, path + ": cannot write"};
  } catch (const rays::RaysError& e) {
    throw CommandError{kExitFailure, e.what()};
  }
}

// The same checks the service makes, here with the index in the whole file.
void check_rays(const RayTable& t, const std::string& source) {
  for (size_t i = 0; i < t.rays.size(); ++i) {
    if (const std::string p = rays::check_ray(t.rays[i], i); !p.empty()) {
      throw CommandError{kExitBadInput, source + ": " + p + " (rays count from 0 in file order)"};
    }
  }
}

// --fields: the service sends only these, and the output has only their columns. Checked before
// anything is read. With --occlusion it is refused rather than ignored: an occlusion query
// answers `hit` alone, so a mask there is a mistake about what the run produces.
HitFields fields_of(const RaysArgs& a) {
  if (!a.fields) return HitFields::all();
  if (a.occlusion) {
    throw CommandError{kExitBadInput, "--fields chooses the columns of nearest hits; --occlusion answers hit alone: "
                                      "pass one or the other"};
  }
  try {
    return rays::parse_hit_fields(*a.fields);
  } catch (const rays::RaysError& e) {
    throw CommandError{kExitBadInput, std::string("--fields: ") + e.what()};
  }
}

HitTable trace_locally(const RaysArgs& a, const RayTable& rays) {
  std::shared_ptr<const Scene> scene;
  try {
    scene = std::make_shared<const Scene>(load_scene(a.scene));
  } catch (const SceneError& e) {
    throw CommandError{kExitBadInput, e.what()};
  }
  if (a.frame < 0 || a.frame >= scene->frame_count()) {
    throw CommandError{kExitBadInput, "--frame " + std::to_string(a.frame) + ": the scene has frames 0-" +
                                          std::to_string(scene->frame_count() - 1)};
  }
  const rays::RayTracer tracer(scene, make_render_scene(*scene, a.frame));
  HitTable h;
  for (const SceneObject& o : scene->objects) h.objects.push_back(o.name);
  for (const Material& m : scene->materials) h.materials.push_back(m.name);
  h.occlusion = a.occlusion;
  rays::trace_batch(tracer, rays.rays, a.occlusion, &h.hits);
  return h;
}

std::string describe_rays_server(const grpc::Status& s, const std::string& address) {
  if (s.error_code() == grpc::StatusCode::UNAVAILABLE) {
    return "cannot reach the ray service at " + address + " (" + s.error_message() +
           "). Start one with: tessera-rays --listen " + address + " --coordinator COORDINATOR";
  }
  return "the ray service at " + address + ": " + s.error_message();
}

// The ray servers the coordinator lists, in the order to try them: only those this client can
// talk to (TLS or plaintext, as the client's --tls-ca says); the fewest rays in flight at their
// last announcement first, then the fewest rays served since they started (over many queries
// that spreads the load); ties in random order, so clients that start together do not all pick
// the same server.
std::vector<std::string> listed_ray_servers(FarmClient& coordinator, bool tls) {
  v1::ListRayServersResponse resp;
  auto ctx = coordinator.context();
  const grpc::Status s = coordinator.stub().ListRayServers(ctx.get(), {}, &resp);
  if (!s.ok()) throw CommandError{kExitFailure, coordinator.describe(s, "listing ray servers")};
  std::vector<v1::RayServerDescription> usable;
  for (const v1::RayServerInfo& r : resp.servers()) {
    if (r.server().tls() == tls) usable.push_back(r.server());
  }
  const std::string& at = coordinator.address();
  if (resp.servers().empty()) {
    throw CommandError{kExitFailure, "no ray server is announced to the coordinator at " + at +
                                         "; start tessera-rays --coordinator " + at + ", or pass --server HOST:PORT"};
  }
  if (usable.empty()) {
    throw CommandError{kExitFailure, std::to_string(resp.servers_size()) +
                                         " ray server(s) announced to the coordinator at " + at + ", but " +
                                         (tls ? "none speaks TLS, which this client uses (--tls-ca / $TESSERA_TLS_CA)"
                                              : "all need TLS: pass --tls-ca CA.pem (or set TESSERA_TLS_CA)")};
  }
  std::shuffle(usable.begin(), usable.end(), std::mt19937(std::random_device{}()));
  std::stable_sort(usable.begin(), usable.end(), [](const auto& x, const auto& y) {
    return std::pair(x.rays_in_flight(), x.rays()) < std::pair(y.rays_in_flight(), y.rays());
  });
  std::vector<std::string> out;
  for (const auto& d : usable) out.push_back(d.address());
  return out;
}

// Whether the channel connects within `within`. A refused connection answers at once (the first
// failure counts: the server is listed but not listening, so the next one is tried).
bool connects(grpc::Channel& channel, std::chrono::seconds within, std::string* why) {
  const auto deadline = std::chrono::system_clock::now() + within;
  for (auto state = channel.GetState(true); state != GRPC_CHANNEL_READY; state = channel.GetState(true)) {
    if (state == GRPC_CHANNEL_TRANSIENT_FAILURE || state == GRPC_CHANNEL_SHUTDOWN) {
      *why = "cannot connect";
      return false;
    }
    if (!channel.WaitForStateChange(state, deadline)) {
      *why = "no connection in " + std::to_string(within.count()) + " s";
      return false;
    }
  }
  return true;
}

// The scene as a ray server sees it (objects, materials); the first call on a server loads it.
// A server found through the coordinator that does not connect in 5 s, or cannot reach the
// coordinator itself, returns nullopt with `*why`: the caller tries the next one.
std::optional<v1::SceneDescription> describe_on(v1::RayService::Stub& stub, grpc::Channel& channel,
                                                const std::string& address, const v1::SceneRef& ref, bool listed,
                                                std::chrono::system_clock::time_point deadline, std::string* why) {
  if (listed && !connects(channel, std::chrono::seconds(5), why)) return std::nullopt;
  grpc::ClientContext ctx;
  ctx.set_deadline(deadline);  // the run's: the first use of a scene on a server loads it
  v1::SceneDescription d;
  const grpc::Status s = stub.DescribeScene(&ctx, ref, &d);
  if (s.ok()) return d;
  if (listed && s.error_code() == grpc::StatusCode::UNAVAILABLE) {
    *why = s.error_message();
    return std::nullopt;
  }
  if (s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
    throw CommandError{kExitFailure, "the ray service at " + address + " did not describe the scene within --timeout"};
  }
  throw CommandError{s.error_code() == grpc::StatusCode::INVALID_ARGUMENT ? kExitBadInput : kExitFailure,
                     describe_rays_server(s, address)};
}

// Traces the rays on the server at `used` (which described the scene `ref`), appending the hits
// to h->hits; throws CommandError if the stream fails or ends early.
void trace_stream(v1::RayService::Stub& stub, const v1::SceneRef& ref, const RaysArgs& a, const RayTable& rays,
                  HitFields fields, std::chrono::system_clock::time_point deadline, const std::string& used,
                  HitTable* h) {
  // One stream; a writer thread keeps every batch in flight while this one reads the answers
  // (they come back in order), so the network and the tracing overlap.
  grpc::ClientContext ctx;
  // The run's deadline for the whole stream too: a server that stops answering mid-way ends the
  // run instead of hanging it.
  ctx.set_deadline(deadline);
  auto stream = stub.TraceStream(&ctx);
  const size_t n = rays.rays.size(), batch = size_t(a.batch);
  std::thread writer([&] {
    for (size_t begin = 0; begin < n; begin += batch) {
      const size_t end = std::min(n, begin + batch);
      v1::TraceRequest req;
      if (begin == 0) *req.mutable_scene() = ref;
      req.set_occlusion(a.occlusion);
      rays::encode_fields(fields, &req);
      rays::encode_rays({rays.rays.begin() + long(begin), rays.rays.begin() + long(end)}, {}, &req);
      if (!stream->Write(req)) break;  // the stream failed: Finish() says why
    }
    stream->WritesDone();
  });
  v1::TraceResponse resp;
  std::string problem;
  for (size_t begin = 0; begin < n && stream->Read(&resp); begin += batch) {
    const size_t count = std::min(n, begin + batch) - begin;
    try {
      std::vector<rays::WorldHit> hits = rays::decode_hits(resp, count, a.occlusion, fields);
      h->hits.insert(h->hits.end(), hits.begin(), hits.end());
    } catch (const rays::RaysError& e) {
      problem = e.what();
      ctx.TryCancel();
      break;
    }
  }
  writer.join();
  const grpc::Status s = stream->Finish();
  if (!problem.empty()) throw CommandError{kExitFailure, "the ray service at " + used + " answered badly: " + problem};
  if (s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
    throw CommandError{kExitFailure, "the ray service at " + used + " did not answer all " + std::to_string(n) +
                                         " rays within --timeout " + std::to_string(a.timeout) + " s"};
  }
  if (!s.ok()) {
    throw CommandError{s.error_code() == grpc::StatusCode::INVALID_ARGUMENT ? kExitBadInput : kExitFailure,
                       describe_rays_server(s, used)};
  }
  if (h->hits.size() != n) throw CommandError{kExitFailure, "the ray service at " + used + " ended the stream early"};
}

// Traces on --server, or on the first ray server the coordinator lists that answers; `*used`
// is its address.
HitTable trace_remotely(const RaysArgs& a, const RayTable& rays, HitFields fields, std::string* used) {
  const auto deadline = std::chrono::system_clock::now() + std::chrono::seconds(a.timeout);
  Scene scene;
  try {
    scene = load_scene(a.scene);
  } catch (const SceneError& e) {
    throw CommandError{kExitBadInput, e.what()};
  }
  farm::ChannelSecurity security;
  farm::BuiltBundle bundle;
  std::vector<std::string> servers{a.server};
  const bool listed = a.server.empty();
  try {
    security = resolve_security(a.security);
    bundle = farm::make_bundle(a.scene, scene.dependencies);
    FarmClient coordinator(resolve_coordinator(a.coordinator), security);
    if (listed) servers = listed_ray_servers(coordinator, !security.tls_ca.empty());  // before the upload: fail early
    if (upload_bundle_if_missing(coordinator, bundle)) {
      std::fprintf(stderr, "uploaded scene bundle %s to %s\n", bundle.sha256.substr(0, 12).c_str(),
                   coordinator.address().c_str());
    }
  } catch (const std::exception& e) {
    throw CommandError{kExitFailure, e.what()};
  }
  v1::SceneRef ref;
  ref.set_bundle_sha256(bundle.sha256);
  ref.set_frame(a.frame);
  HitTable h;
  h.occlusion = a.occlusion;
  std::unique_ptr<v1::RayService::Stub> stub;
  std::string unreachable;
  for (const std::string& address : servers) {
    const auto channel = farm::make_coordinator_channel(address, security);
    auto candidate = v1::RayService::NewStub(channel);
    std::string why;
    if (auto d = describe_on(*candidate, *channel, address, ref, listed, deadline, &why)) {
      h.objects.assign(d->objects().begin(), d->objects().end());
      h.materials.assign(d->materials().begin(), d->materials().end());
      stub = std::move(candidate);
      *used = address;
      break;
    }
    std::fprintf(stderr, "ray server %s (listed by the coordinator) does not answer (%s); trying the next\n",
                 address.c_str(), why.c_str());
    unreachable += (unreachable.empty() ? "" : "; ") + address + ": " + why;
  }
  if (!stub) {
    throw CommandError{kExitFailure, "none of the " + std::to_string(servers.size()) +
                                         " ray server(s) the coordinator lists answered (" + unreachable +
                                         "); pass --server HOST:PORT to name one"};
  }
  trace_stream(*stub, ref, a, rays, fields, deadline, *used, &h);
  return h;
}

int run_rays(const RaysArgs& a) {
  const HitFields fields = fields_of(a);
  const RayTable rays = read_rays(a.in);
  check_rays(rays, a.in);
  const auto start = std::chrono::steady_clock::now();
  // In-process unless a server is named or the coordinator is given to find one: an environment
  // variable ($TESSERA_COORDINATOR) alone does not move the tracing off this machine.
  std::string used;
  HitTable hits =
      a.server.empty() && a.coordinator.empty() ? trace_locally(a, rays) : trace_remotely(a, rays, fields, &used);
  hits.fields = fields;  // in-process every field is traced; the mask selects the columns
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  write_hits(a.out, rays, hits);
  size_t n_hit = 0;
  for (const rays::WorldHit& w : hits.hits) n_hit += w.hit;
  std::printf("%zu rays, %zu %s, %.3f s (scene load included)%s\n", rays.rays.size(), n_hit,
              a.occlusion ? "occluded" : "hits", seconds, used.empty() ? "" : (", via " + used).c_str());
  return 0;
}

}  // namespace

void register_rays_command(CLI::App& app) {
  auto a = std::make_shared<RaysArgs>();
  CLI::App* cmd = app.add_subcommand(
      "rays", "Nearest hits (or occlusion) of a file of rays: CSV with a header, or .npy (docs/rays.md)");
  cmd->add_option("scene", a->scene, "Scene file (JSON, see docs/scene-format.md)")->required();
  cmd->add_option("--in", a->in, "Rays: CSV (ox,oy,oz,dx,dy,dz[,tmin,tmax,id]) or .npy (n x 6, 8 or 9)")->required();
  cmd->add_option("--out", a->out, "Hits: CSV, or .npy (a structured array)")->required();
  cmd->add_option("--frame", a->frame, "Frame of an animated scene")->capture_default_str();
  cmd->add_flag("--occlusion", a->occlusion, "Only whether something lies in (tmin, tmax): line of sight");
  cmd->add_option("--fields", a->fields,
                  "Nearest hits: only these columns besides hit (and id), a comma list of t, point, normal, "
                  "shading_normal, barycentrics, object, primitive, material; a ray server sends only these "
                  "(default: all)");
  cmd->add_option("--server", a->server, "tessera-rays HOST:PORT: trace there instead of in-process");
  cmd->add_option("--coordinator", a->coordinator,
                  std::string("The coordinator the bundle is uploaded to (with --server; default: "
                              "$TESSERA_COORDINATOR, else ") +
                      farm::kDefaultCoordinator +
                      "). Without --server: also trace on a ray server it lists (`tessera rayservers`)");
  cmd->add_option("--batch", a->batch, "With a ray server: rays per request")
      ->check(CLI::Range(1, 1 << 24))->capture_default_str();
  cmd->add_option("--timeout", a->timeout, "With a ray server: seconds the whole run may take")
      ->check(CLI::Range(1, 7 * 24 * 3600))->capture_default_str();
  // The farm commands' flags: one client token and CA for the coordinator and the ray server.
  add_security_flags(cmd, &a->security, "coordinator or ray server");
  cmd->callback([a] { guarded("rays", [a] { return run_rays(*a); }); });
}

}  // namespace tessera::cli

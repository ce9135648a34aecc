// SPDX-License-Identifier: Apache-2.0
#include "ray_service.h"

#include <spdlog/spdlog.h>

#include "rays/parallel_trace.h"
#include "rays/ray_codec.h"
#include "render/embree_device.h"

namespace tessera::rayserver {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;
// lib/rays: the tracer and the wire form of its rays and hits.
using rays::check_rays;
using rays::for_each_chunk;
using rays::hit_field_names;
using rays::HitArrays;
using rays::HitFields;
using rays::kParallelBatch;
using rays::read_fields;
using rays::read_rays;
using rays::WorldHit;
using rays::WorldRay;

RayServiceImpl::RayServiceImpl(SceneSource scenes, farm::Authenticator auth, RayServiceOptions options)
    : scenes_(std::move(scenes)), auth_(std::move(auth)), options_(options), arena_(std::max(1, options.threads)) {}

Status RayServiceImpl::answer(const rays::RayTracer& tracer, const v1::TraceRequest& req,
                              v1::TraceResponse* resp) {
  const int64_t n = req.directions_size() / 3;
  if (n > options_.max_batch_rays) {
    // Counted before anything is decoded: a huge batch costs its parse only.
    return Status(StatusCode::INVALID_ARGUMENT, "batch of " + std::to_string(n) +
                                                    " rays (directions / 3) is over this server's limit " +
                                                    std::to_string(options_.max_batch_rays) +
                                                    " (tessera-rays --max-batch-rays): send smaller batches");
  }
  // The mask is checked on occlusion queries too (which answer `hit` alone): a bad request is
  // refused whatever it asks.
  HitFields fields;
  if (std::string p = read_fields(req, &fields); !p.empty()) return Status(StatusCode::INVALID_ARGUMENT, p);
  if (std::string p = check_rays(req); !p.empty()) return Status(StatusCode::INVALID_ARGUMENT, p);
  // Chunk by chunk, straight from the request's arrays to the response's: a chunk's rays and
  // hits stay in cache (batch-sized struct arrays, 128 bytes a ray, did not at 65,536 rays).
  // Only the asked fields' arrays are sized and filled; the rest of `resp` is empty (a new
  // response, or a stream's cleared one).
  const bool occlusion = req.occlusion();
  if (spdlog::should_log(spdlog::level::debug)) {  // what clients ask for (--log-level debug)
    spdlog::debug("batch of {} rays: {}", n, occlusion ? "occlusion" : "nearest hits, fields " + hit_field_names(fields));
  }
  const HitArrays out(resp, size_t(n), occlusion, fields);
  auto run = [&](size_t begin, size_t end) {
    // Per thread, at most kChunk rays (~128 KiB): nothing allocated after a thread's first chunk.
    // Nearest hits go straight into the response's arrays (every asked field of every ray);
    // occlusion answers through WorldHit's flag (all it sends).
    thread_local std::vector<WorldRay> rays;
    thread_local std::vector<WorldHit> hits;
    rays.resize(end - begin);
    read_rays(req, begin, end, rays.data());
    if (!occlusion) {
      tracer.nearest_into(rays.data(), rays.size(), out.columns(), begin);
      return;
    }
    hits.resize(end - begin);
    tracer.occluded(rays.data(), rays.size(), hits.data());
    out.write(begin, hits);
  };
  // Counted while traced: the load a ray server announces to the coordinator (announcer.h).
  in_flight_ += uint64_t(n);
  struct Done {
    std::atomic<uint64_t>& in_flight;
    uint64_t n;
    ~Done() { in_flight -= n; }
  } done{in_flight_, uint64_t(n)};
  // Small batches run on the gRPC thread that received them (concurrent clients in parallel);
  // large ones are split on the service's arena, so --threads bounds the cores they take.
  if (size_t(n) <= kParallelBatch) for_each_chunk(size_t(n), run);
  else arena_.execute([&] { for_each_chunk(size_t(n), run); });
  requests_ += 1;
  rays_ += uint64_t(n);
  *resp->mutable_ids() = req.ids();
  return Status::OK;
}

Status RayServiceImpl::Trace(grpc::ServerContext* ctx, const v1::TraceRequest* req, v1::TraceResponse* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return s;
  if (!req->has_scene()) return Status(StatusCode::INVALID_ARGUMENT, "scene: required (bundle_sha256 and frame)");
  std::shared_ptr<const rays::RayTracer> tracer;
  if (Status s = scenes_(req->scene().bundle_sha256(), req->scene().frame(), &tracer); !s.ok()) return s;
  return answer(*tracer, *req, resp);
}

Status RayServiceImpl::TraceStream(grpc::ServerContext* ctx,
                                   grpc::ServerReaderWriter<v1::TraceResponse, v1::TraceRequest>* stream) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return s;
  std::shared_ptr<const rays::RayTracer> tracer;
  v1::SceneRef current;
  // Read() parses into `req` and answer() fills `resp` keeping their arrays' capacity, so these
  // are allocated by the first batch only.
  v1::TraceRequest req;
  v1::TraceResponse resp;
  for (int64_t batch = 0; stream->Read(&req); ++batch) {
    // The scene is looked up when it changes, not per batch.
    if (req.has_scene() && (!tracer || req.scene().bundle_sha256() != current.bundle_sha256() ||
                            req.scene().frame() != current.frame())) {
      if (Status s = scenes_(req.scene().bundle_sha256(), req.scene().frame(), &tracer); !s.ok()) return s;
      current = req.scene();
    }
    if (!tracer) {
      return Status(StatusCode::INVALID_ARGUMENT, "batch 0: scene required on a stream's first request");
    }
    resp.Clear();
    if (Status s = answer(*tracer, req, &resp); !s.ok()) {
      return Status(s.error_code(), "batch " + std::to_string(batch) + ": " + s.error_message());
    }
    if (!stream->Write(resp)) break;  // the client went away
  }
  return Status::OK;
}

Status RayServiceImpl::DescribeScene(grpc::ServerContext* ctx, const v1::SceneRef* req, v1::SceneDescription* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return s;
  std::shared_ptr<const rays::RayTracer> tracer;
  if (Status s = scenes_(req->bundle_sha256(), req->frame(), &tracer); !s.ok()) return s;
  const Scene& scene = tracer->scene();
  for (const SceneObject& o : scene.objects) {
    resp->add_objects(o.name);
    resp->add_object_kinds(o.type == SceneObject::Type::kMesh     ? "mesh"
                           : o.type == SceneObject::Type::kSphere ? "sphere"
                                                                  : "plane");
  }
  for (const Material& m : scene.materials) resp->add_materials(m.name);
  resp->set_frame_count(scene.frame_count());
  resp->set_triangles(triangle_count(tracer->frame()));
  resp->set_embree_isa(embree_isa());
  resp->set_max_batch_rays(options_.max_batch_rays);
  return Status::OK;
}

RayServiceCounters RayServiceImpl::counters() const {
  return RayServiceCounters{requests_.load(), rays_.load(), in_flight_.load()};
}

}  // namespace tessera::rayserver

// SPDX-License-Identifier: Apache-2.0
// tessera.v1.RayService over a SceneSource: checks the token, the batch size and every ray,
// then traces with RayTracer (lib/rays), large batches split across a TBB arena. A thin
// adapter: the tracing itself knows nothing of gRPC.
#pragma once

#include <tbb/task_arena.h>

#include <atomic>
#include <cstdint>

#include "farm/auth.h"
#include "scene_source.h"
#include "tessera/v1/ray_service.grpc.pb.h"

namespace tessera::rayserver {

struct RayServiceOptions {
  // Rays per request. A request of 2^18 rays is ~16 MiB and its answer ~21 MiB, inside the
  // farm's 64 MiB message limit with room to spare.
  int64_t max_batch_rays = int64_t(1) << 18;
  // Threads that large batches (> kParallelBatch rays) are split across, all requests together.
  int threads = 1;
};

// What the service has done since it started (announced to the coordinator, announcer.h).
struct RayServiceCounters {
  uint64_t requests = 0;        // batches answered: Trace calls and stream requests
  uint64_t rays = 0;            // rays traced
  uint64_t rays_in_flight = 0;  // rays being traced now
};

class RayServiceImpl final : public tessera::v1::RayService::Service {
 public:
  RayServiceImpl(SceneSource scenes, farm::Authenticator auth, RayServiceOptions options);

  grpc::Status Trace(grpc::ServerContext* ctx, const tessera::v1::TraceRequest* req,
                     tessera::v1::TraceResponse* resp) override;
  grpc::Status TraceStream(
      grpc::ServerContext* ctx,
      grpc::ServerReaderWriter<tessera::v1::TraceResponse, tessera::v1::TraceRequest>* stream) override;
  grpc::Status DescribeScene(grpc::ServerContext* ctx, const tessera::v1::SceneRef* req,
                             tessera::v1::SceneDescription* resp) override;
  RayServiceCounters counters() const;

 private:
  // One batch on a tracer, answered with the fields its mask asks for: INVALID_ARGUMENT naming
  // the ray and field (or fields[k]) for bad input.
  grpc::Status answer(const rays::RayTracer& tracer, const tessera::v1::TraceRequest& req,
                      tessera::v1::TraceResponse* resp);

  SceneSource scenes_;
  farm::Authenticator auth_;
  RayServiceOptions options_;
  tbb::task_arena arena_;
  std::atomic<uint64_t> requests_{0}, rays_{0}, in_flight_{0};
};

}  // namespace tessera::rayserver

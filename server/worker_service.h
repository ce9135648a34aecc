// SPDX-License-Identifier: Apache-2.0
// tessera.v1.WorkerService on the callback API: one bidirectional session per worker, and bundle
// fetches.
#pragma once

#include "farm/auth.h"
#include "coordinator.h"
#include "tessera/v1/worker_service.grpc.pb.h"

namespace tessera::server {

class WorkerServiceImpl final : public tessera::v1::WorkerService::CallbackService {
 public:
  // Every method first checks the worker token (auth.h).
  explicit WorkerServiceImpl(Coordinator& c, farm::Authenticator auth = {}) : coord_(c), auth_(std::move(auth)) {}

  grpc::ServerBidiReactor<tessera::v1::WorkerMessage, tessera::v1::CoordinatorMessage>* Connect(
      grpc::CallbackServerContext* ctx) override;
  grpc::ServerWriteReactor<tessera::v1::BundleChunk>* FetchBundle(grpc::CallbackServerContext* ctx,
                                                                  const tessera::v1::FetchBundleRequest* req) override;
  // A tessera-rays server announcing itself (ray_servers.h), with the worker token.
  grpc::ServerUnaryReactor* AnnounceRayServer(grpc::CallbackServerContext* ctx,
                                              const tessera::v1::RayServerAnnouncement* req,
                                              tessera::v1::RayServerAnnouncementAck* ack) override;

 private:
  Coordinator& coord_;
  farm::Authenticator auth_;
};

}  // namespace tessera::server

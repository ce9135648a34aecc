// tessera.v1.ClientService on the callback API: thin adapters onto the Coordinator.
#pragma once

#include "auth.h"
#include "coordinator.h"
#include "request_limits.h"
#include "tessera/v1/client_service.grpc.pb.h"

namespace tessera::server {

class ClientServiceImpl final : public tessera::v1::ClientService::CallbackService {
 public:
  // Every method first checks the client token (auth.h); uploads and submissions the limits.
  // The per-client quota starts from the active jobs the coordinator restored: a restart does
  // not give every client a fresh allowance.
  explicit ClientServiceImpl(Coordinator& c, Authenticator auth = {}, Limits limits = {})
      : coord_(c), auth_(std::move(auth)), limits_(limits), quota_(limits.max_jobs_per_client) {
    for (const auto& [owner, job] : coord_.active_jobs_by_owner()) quota_.restore(owner, job);
  }

  grpc::ServerUnaryReactor* HasBundle(grpc::CallbackServerContext*, const tessera::v1::HasBundleRequest*,
                                      tessera::v1::HasBundleResponse*) override;
  grpc::ServerReadReactor<tessera::v1::BundleChunk>* UploadBundle(grpc::CallbackServerContext*,
                                                                  tessera::v1::UploadBundleResponse*) override;
  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext*, const tessera::v1::SubmitJobRequest*,
                                      tessera::v1::JobStatus*) override;
  grpc::ServerWriteReactor<tessera::v1::WatchJobEvent>* WatchJob(grpc::CallbackServerContext*,
                                                                 const tessera::v1::WatchJobRequest*) override;
  grpc::ServerUnaryReactor* AckFrame(grpc::CallbackServerContext*, const tessera::v1::AckFrameRequest*,
                                     tessera::v1::AckFrameResponse*) override;
  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext*, const tessera::v1::GetJobRequest*,
                                   tessera::v1::JobStatus*) override;
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext*, const tessera::v1::ListJobsRequest*,
                                     tessera::v1::ListJobsResponse*) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext*, const tessera::v1::CancelJobRequest*,
                                      tessera::v1::JobStatus*) override;
  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext*, const tessera::v1::ListWorkersRequest*,
                                        tessera::v1::ListWorkersResponse*) override;

 private:

  Coordinator& coord_;
  Authenticator auth_;
  Limits limits_;
  JobQuota quota_;
};

}  // namespace tessera::server

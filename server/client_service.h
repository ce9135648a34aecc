// tessera.v1.ClientService on the callback API: thin adapters onto the Coordinator.
#pragma once

#include "coordinator.h"
#include "tessera/v1/client_service.grpc.pb.h"

namespace tessera::server {

class ClientServiceImpl final : public tessera::v1::ClientService::CallbackService {
 public:
  explicit ClientServiceImpl(Coordinator& c) : coord_(c) {}

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
};

}  // namespace tessera::server

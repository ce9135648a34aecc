// SPDX-License-Identifier: Apache-2.0
// tessera.v1.ClientService on the callback API: thin adapters onto the Coordinator.
#pragma once

#include <set>
#include <string>

#include "farm/auth.h"
#include "bundle_upload.h"
#include "coordinator.h"
#include "job_access.h"
#include "farm/request_limits.h"
#include "job_quota.h"
#include "tessera/v1/client_service.grpc.pb.h"

namespace tessera::server {

// WatchJob is a raw method: its stream writes bytes, so that stored tiles go out as they are
// stored (watch_wire.h); its request is parsed here like any other.
class ClientServiceImpl final
    : public tessera::v1::ClientService::WithRawCallbackMethod_WatchJob<tessera::v1::ClientService::CallbackService> {
 public:
  // Every method first checks the client token (auth.h); uploads and submissions the limits.
  // The per-client quota starts from the active jobs the coordinator restored: a restart does
  // not give every client a fresh allowance.
  // `admins`: identities (job_access.h) that may watch, cancel and acknowledge any client's jobs.
  explicit ClientServiceImpl(Coordinator& c, farm::Authenticator auth = {}, farm::Limits limits = {},
                             std::set<std::string> admins = {})
      : coord_(c), auth_(std::move(auth)), limits_(limits), quota_(limits.max_jobs_per_client),
        admins_(std::move(admins)),
        uploads_(limits.max_concurrent_uploads,
                 std::chrono::milliseconds(int64_t(limits.upload_idle_seconds * 1000.0))) {
    for (const auto& [owner, job] : coord_.active_jobs_by_owner()) quota_.restore(owner, job);
  }

  grpc::ServerUnaryReactor* HasBundle(grpc::CallbackServerContext*, const tessera::v1::HasBundleRequest*,
                                      tessera::v1::HasBundleResponse*) override;
  grpc::ServerReadReactor<tessera::v1::BundleChunk>* UploadBundle(grpc::CallbackServerContext*,
                                                                  tessera::v1::UploadBundleResponse*) override;
  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext*, const tessera::v1::SubmitJobRequest*,
                                      tessera::v1::JobStatus*) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* WatchJob(grpc::CallbackServerContext*,
                                                       const grpc::ByteBuffer* request) override;
  grpc::ServerUnaryReactor* AckFrame(grpc::CallbackServerContext*, const tessera::v1::AckFrameRequest*,
                                     tessera::v1::AckFrameResponse*) override;
  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext*, const tessera::v1::GetJobRequest*,
                                   tessera::v1::JobStatus*) override;
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext*, const tessera::v1::ListJobsRequest*,
                                     tessera::v1::ListJobsResponse*) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext*, const tessera::v1::CancelJobRequest*,
                                      tessera::v1::JobStatus*) override;
  grpc::ServerUnaryReactor* SetJobPriority(grpc::CallbackServerContext*, const tessera::v1::SetJobPriorityRequest*,
                                           tessera::v1::JobStatus*) override;
  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext*, const tessera::v1::ListWorkersRequest*,
                                        tessera::v1::ListWorkersResponse*) override;
  grpc::ServerUnaryReactor* ListRayServers(grpc::CallbackServerContext*, const tessera::v1::ListRayServersRequest*,
                                           tessera::v1::ListRayServersResponse*) override;

 private:
  // Checks the client token; on success `*caller` is who is calling.
  grpc::Status authenticate(const grpc::CallbackServerContext& ctx, Caller* caller) const;
  // PERMISSION_DENIED unless `caller` may act on the job (job_access.h); OK for an unknown job
  // (the method itself answers NOT_FOUND).
  grpc::Status authorize(const std::string& job, const Caller& caller, const char* action);

  Coordinator& coord_;
  farm::Authenticator auth_;
  farm::Limits limits_;
  JobQuota quota_;
  std::set<std::string> admins_;
  UploadSlots uploads_;
};

}  // namespace tessera::server

#include "client_service.h"

#include <spdlog/spdlog.h>

#include "farm/bundle.h"

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

namespace {

grpc::ServerUnaryReactor* reply(grpc::CallbackServerContext* ctx, Status s) {
  auto* r = ctx->DefaultReactor();
  r->Finish(std::move(s));
  return r;
}

// Largest bundle accepted (issue 8 makes this configurable); protects the coordinator's memory.
constexpr size_t kMaxBundleBytes = size_t(2) << 30;

class UploadReactor : public grpc::ServerReadReactor<v1::BundleChunk> {
 public:
  UploadReactor(BundleStore& store, v1::UploadBundleResponse* resp) : store_(store), resp_(resp) {
    StartRead(&chunk_);
  }
  void OnReadDone(bool ok) override {
    if (ok) {
      if (sha_.empty()) sha_ = chunk_.sha256();
      bytes_ += chunk_.data();
      if (bytes_.size() > kMaxBundleBytes) {
        Finish(Status(StatusCode::RESOURCE_EXHAUSTED, "bundle larger than the 2 GiB limit"));
        return;
      }
      StartRead(&chunk_);
      return;
    }
    // End of the client's stream (or a broken one: then Finish is harmless).
    if (sha_.empty()) {
      Finish(Status(StatusCode::INVALID_ARGUMENT, "the first chunk must carry the bundle's sha256"));
      return;
    }
    try {
      store_.put(sha_, bytes_);
      resp_->set_sha256(sha_);
      resp_->set_size(bytes_.size());
      spdlog::info("bundle {} stored ({} bytes)", sha_, bytes_.size());
      Finish(Status::OK);
    } catch (const farm::BundleError& e) {
      Finish(Status(StatusCode::INVALID_ARGUMENT, std::string("bundle refused: ") + e.what()));
    } catch (const std::exception& e) {
      Finish(Status(StatusCode::INTERNAL, std::string("cannot store the bundle: ") + e.what()));
    }
  }
  void OnDone() override { delete this; }

 private:
  BundleStore& store_;
  v1::UploadBundleResponse* resp_;
  v1::BundleChunk chunk_;
  std::string sha_;
  std::string bytes_;
};

// The watch stream: the coordinator pushes events into the outbox; this reactor writes them.
class WatchReactor : public grpc::ServerWriteReactor<v1::WatchJobEvent> {
 public:
  struct Sink : WatchSink {
    explicit Sink(WatchReactor* r) : box(r) {}
    void push(v1::WatchJobEvent m) override { box.push(std::move(m)); }
    void finish(Status s) override { box.finish(std::move(s)); }
    void pump() override { box.pump(); }
    Outbox<WatchReactor, v1::WatchJobEvent> box;
  };

  WatchReactor(Coordinator& c, const std::string& job) : coord_(c), sink_(std::make_shared<Sink>(this)) {
    Status s = coord_.attach_watcher(job, sink_);
    if (!s.ok()) {
      sink_->finish(s);
      sink_->pump();
    }
  }
  void OnWriteDone(bool ok) override { sink_->box.on_write_done(ok); }
  void OnCancel() override {
    // The client went away (or the server is shutting down): stop feeding this stream.
    coord_.detach_watcher(sink_);
    sink_->finish(Status(StatusCode::CANCELLED, "watch cancelled"));
    sink_->pump();
  }
  void OnDone() override {
    coord_.detach_watcher(sink_);
    sink_->box.on_done();
    delete this;
  }

 private:
  Coordinator& coord_;
  std::shared_ptr<Sink> sink_;
};

}  // namespace

grpc::ServerUnaryReactor* ClientServiceImpl::HasBundle(grpc::CallbackServerContext* ctx,
                                                       const v1::HasBundleRequest* req, v1::HasBundleResponse* resp) {
  if (!farm::is_sha256_hex(req->sha256())) {
    return reply(ctx, Status(StatusCode::INVALID_ARGUMENT, "'" + req->sha256() + "' is not a lower-case hex SHA-256"));
  }
  resp->set_present(coord_.bundles().has(req->sha256()));
  return reply(ctx, Status::OK);
}

grpc::ServerReadReactor<v1::BundleChunk>* ClientServiceImpl::UploadBundle(grpc::CallbackServerContext*,
                                                                         v1::UploadBundleResponse* resp) {
  return new UploadReactor(coord_.bundles(), resp);
}

grpc::ServerUnaryReactor* ClientServiceImpl::SubmitJob(grpc::CallbackServerContext* ctx,
                                                       const v1::SubmitJobRequest* req, v1::JobStatus* resp) {
  return reply(ctx, coord_.submit(*req, resp));
}

grpc::ServerWriteReactor<v1::WatchJobEvent>* ClientServiceImpl::WatchJob(grpc::CallbackServerContext*,
                                                                        const v1::WatchJobRequest* req) {
  return new WatchReactor(coord_, req->job_id());
}

grpc::ServerUnaryReactor* ClientServiceImpl::AckFrame(grpc::CallbackServerContext* ctx, const v1::AckFrameRequest* req,
                                                      v1::AckFrameResponse*) {
  return reply(ctx, coord_.ack_frame(req->job_id(), req->frame()));
}

grpc::ServerUnaryReactor* ClientServiceImpl::GetJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                                    v1::JobStatus* resp) {
  return reply(ctx, coord_.get_job(req->job_id(), resp));
}

grpc::ServerUnaryReactor* ClientServiceImpl::ListJobs(grpc::CallbackServerContext* ctx, const v1::ListJobsRequest*,
                                                      v1::ListJobsResponse* resp) {
  coord_.list_jobs(resp);
  return reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* ClientServiceImpl::CancelJob(grpc::CallbackServerContext* ctx,
                                                       const v1::CancelJobRequest* req, v1::JobStatus* resp) {
  return reply(ctx, coord_.cancel(req->job_id(), resp));
}

grpc::ServerUnaryReactor* ClientServiceImpl::ListWorkers(grpc::CallbackServerContext* ctx,
                                                         const v1::ListWorkersRequest*,
                                                         v1::ListWorkersResponse* resp) {
  coord_.list_workers(resp);
  return reply(ctx, Status::OK);
}

}  // namespace tessera::server

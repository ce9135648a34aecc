// SPDX-License-Identifier: Apache-2.0
#include "client_service.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "bundle_upload.h"
#include "farm/bundle.h"
#include "farm/client_identity.h"
#include "farm/overrides_codec.h"
#include "farm/peer_text.h"
#include "scene/scene_parser.h"
#include "stream_sink.h"
#include "watch_wire.h"

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

// One upload, holding one of the slots (bundle_upload.h): each chunk to disk as it comes; ended by
// the slots' watchdog when it waits too long for the next one.
class UploadReactor : public grpc::ServerReadReactor<v1::BundleChunk>, private UploadSlots::Waiter {
 public:
  UploadReactor(BundleStore& store, v1::UploadBundleResponse* resp, int64_t max_bytes, UploadSlots& slots)
      : store_(store), resp_(resp), max_bytes_(max_bytes), slots_(slots) {
    try {
      upload_ = std::make_unique<BundleUpload>(store_.dir());
    } catch (const std::exception& e) {
      finish(Status(StatusCode::RESOURCE_EXHAUSTED, std::string("cannot take the upload: ") + e.what()));
      return;
    }
    read_next();
  }
  void OnReadDone(bool ok) override {
    slots_.waiting(this, false);
    {
      std::lock_guard lock(mu_);
      if (finished_) return;  // ended while it waited (idle_too_long): nothing more to do
    }
    if (!ok) return stored();  // the end of the client's stream (or a broken one: then Finish is harmless)
    if (sha_.empty()) sha_ = chunk_.sha256();
    // Checked per chunk: the upload is refused as soon as it is over the limit.
    if (upload_->size() + int64_t(chunk_.data().size()) > max_bytes_) {
      return finish(farm::over_limit(StatusCode::RESOURCE_EXHAUSTED, "the scene bundle's size in bytes (so far)",
                                     upload_->size() + int64_t(chunk_.data().size()), "--max-bundle-bytes",
                                     max_bytes_));
    }
    try {
      upload_->append(chunk_.data());  // to disk, hashed on the way: one chunk in memory
    } catch (const std::exception& e) {
      return finish(Status(StatusCode::RESOURCE_EXHAUSTED, std::string("cannot store the bundle: ") + e.what()));
    }
    read_next();
  }
  void OnDone() override {
    slots_.release(this);
    delete this;  // the temporary file goes with upload_, unless the store took it
  }

 private:
  // The watchdog, under the slots' lock (so OnDone's release waits for this call).
  void idle_too_long() override {
    spdlog::warn("upload of bundle {} ended: {}", sha_, slots_.idle_status().error_message());
    finish(slots_.idle_status());
  }
  void read_next() {
    slots_.waiting(this, true);  // not under mu_: the watchdog takes the slots' lock, then mu_
    std::lock_guard lock(mu_);
    if (!finished_) StartRead(&chunk_);
  }
  // Finish, once, from whichever thread ends the call first (a read, or the watchdog).
  void finish(Status s) {
    std::lock_guard lock(mu_);
    if (finished_) return;
    finished_ = true;
    Finish(std::move(s));
  }
  void stored() {
    if (sha_.empty()) {
      return finish(Status(StatusCode::INVALID_ARGUMENT, "the first chunk must carry the bundle's sha256"));
    }
    try {
      const std::string actual = upload_->finish();
      if (actual != sha_) {
        return finish(Status(StatusCode::INVALID_ARGUMENT, "bundle refused: bundle bytes hash to " + actual +
                                                               ", not to the announced " + sha_));
      }
      store_.put_file(sha_, upload_->path());
      upload_->taken();
      resp_->set_sha256(sha_);
      resp_->set_size(uint64_t(upload_->size()));
      spdlog::info("bundle {} stored ({} bytes)", sha_, upload_->size());
      finish(Status::OK);
    } catch (const farm::BundleError& e) {
      finish(Status(StatusCode::INVALID_ARGUMENT, std::string("bundle refused: ") + e.what()));
    } catch (const std::exception& e) {
      finish(Status(StatusCode::INTERNAL, std::string("cannot store the bundle: ") + e.what()));
    }
  }

  BundleStore& store_;
  v1::UploadBundleResponse* resp_;
  int64_t max_bytes_;
  UploadSlots& slots_;
  v1::BundleChunk chunk_;
  std::string sha_;
  std::unique_ptr<BundleUpload> upload_;
  std::mutex mu_;  // finished_, and StartRead against Finish
  bool finished_ = false;
};

// The watch stream: the coordinator pushes events into the outbox; this reactor writes them, as
// bytes (watch_wire.h): events it is given as messages are serialized when their turn comes,
// stored tiles are framed around the stored bytes.
class WatchReactor : public grpc::ServerWriteReactor<grpc::ByteBuffer> {
 public:
  static constexpr size_t kMaxTilesPerMessage = 64;
  static constexpr size_t kMaxBatchBytes = size_t(8) << 20;
  using Sink = OutboxSink<WatchReactor, v1::WatchJobEvent, grpc::ByteBuffer>;

  WatchReactor(Coordinator& c, const v1::WatchJobRequest& req) : coord_(c), sink_(std::make_shared<Sink>(this)) {
    // A client that reads `tiles` events gets every tile in one with the tiles queued behind it;
    // any other, one `tile` event a tile. The bounds keep a message far below what a client
    // accepts (64 MiB).
    if (req.tile_batches()) {
      sink_->box.set_batching(batch_event, kMaxTilesPerMessage, kMaxBatchBytes);
    } else {
      sink_->box.set_batching(tile_event, 1, kMaxBatchBytes);
    }
    Status s = coord_.attach_watcher(req.job_id(), sink_, req.deliver_frames());
    if (!s.ok()) {
      sink_->finish(s);
      sink_->pump();
    }
  }
  void OnWriteDone(bool ok) override {
    sink_->box.on_write_done(ok);
    // Flow control: this stream held its job back; once it has caught up, let the job go on.
    if (sink_->throttled.load() && sink_->queued() <= coord_.watch_low_water()) coord_.watcher_drained(sink_);
  }
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
  static void tile_event(grpc::ByteBuffer* out, const SharedTile* tiles, size_t) { *out = tile_event_bytes(tiles[0]); }
  static void batch_event(grpc::ByteBuffer* out, const SharedTile* tiles, size_t n) {
    *out = tile_batch_event_bytes(tiles, n);
  }

  Coordinator& coord_;
  std::shared_ptr<Sink> sink_;
};

}  // namespace

Status ClientServiceImpl::authenticate(const grpc::CallbackServerContext& ctx, Caller* caller) const {
  std::string token_name;
  Status s = auth_.check(ctx, farm::PeerRole::kClient, &token_name);
  if (!s.ok()) return s;
  caller->identity = farm::client_identity(ctx, token_name);
  caller->admin = admins_.count(caller->identity) > 0;
  return s;
}

Status ClientServiceImpl::authorize(const std::string& job, const Caller& caller, const char* action) {
  if (Status s = farm::check_job_id(job); !s.ok()) return s;  // before it is looked up or echoed
  const std::optional<std::string> owner = coord_.job_owner(job);
  if (!owner) return Status::OK;
  Status s = check_job_access(job, *owner, caller, action);
  if (!s.ok()) spdlog::warn("{} refused: {}", caller.identity, s.error_message());
  return s;
}

grpc::ServerUnaryReactor* ClientServiceImpl::HasBundle(grpc::CallbackServerContext* ctx,
                                                       const v1::HasBundleRequest* req, v1::HasBundleResponse* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return reply(ctx, std::move(s));
  if (!farm::is_sha256_hex(req->sha256())) {
    return reply(ctx, Status(StatusCode::INVALID_ARGUMENT,
                             "'" + farm::peer_text(req->sha256(), 80) + "' is not a lower-case hex SHA-256"));
  }
  resp->set_present(coord_.bundles().has(req->sha256()));
  return reply(ctx, Status::OK);
}

grpc::ServerReadReactor<v1::BundleChunk>* ClientServiceImpl::UploadBundle(grpc::CallbackServerContext* ctx,
                                                                         v1::UploadBundleResponse* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) {
    return new farm::Refused<grpc::ServerReadReactor<v1::BundleChunk>>(std::move(s));
  }
  if (Status s = uploads_.acquire(); !s.ok()) {
    return new farm::Refused<grpc::ServerReadReactor<v1::BundleChunk>>(std::move(s));
  }
  return new UploadReactor(coord_.bundles(), resp, limits_.max_bundle_bytes, uploads_);
}

grpc::ServerUnaryReactor* ClientServiceImpl::SubmitJob(grpc::CallbackServerContext* ctx,
                                                       const v1::SubmitJobRequest* req, v1::JobStatus* resp) {
  Caller caller;
  if (Status s = authenticate(*ctx, &caller); !s.ok()) return reply(ctx, std::move(s));
  const std::string& client = caller.identity;
  Status s = quota_.reserve(client, [&](const std::string& job) {
    v1::JobStatus st;
    return coord_.get_job(job, &st).ok() &&
           (st.state() == v1::JOB_STATE_QUEUED || st.state() == v1::JOB_STATE_RUNNING);
  });
  if (!s.ok()) return reply(ctx, std::move(s));
  Admission admission;
  admission.owner = client;
  admission.max_primitives = limits_.max_primitives;
  admission.max_texture_pixels = limits_.max_texture_pixels;
  admission.check = [&](const Scene& scene, int first, int last, int tile) {
    return limits_.check_job(scene, first, last, tile);
  };
  s = coord_.submit(*req, resp, admission);
  quota_.settle(client, s.ok() ? resp->job_id() : std::string());
  if (!s.ok()) spdlog::info("submission from {} refused: {}", client, s.error_message());
  return reply(ctx, std::move(s));
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* ClientServiceImpl::WatchJob(grpc::CallbackServerContext* ctx,
                                                                       const grpc::ByteBuffer* request) {
  Caller caller;
  Status s = authenticate(*ctx, &caller);
  v1::WatchJobRequest req;
  if (s.ok()) {
    grpc::ByteBuffer bytes(*request);  // refers to the same slices: Deserialize consumes its argument
    if (!grpc::SerializationTraits<v1::WatchJobRequest>::Deserialize(&bytes, &req).ok()) {
      s = Status(StatusCode::INVALID_ARGUMENT, "the WatchJobRequest does not parse");
    }
  }
  if (s.ok()) s = authorize(req.job_id(), caller, "watch");
  if (!s.ok()) return new farm::Refused<grpc::ServerWriteReactor<grpc::ByteBuffer>>(std::move(s));
  return new WatchReactor(coord_, req);
}

grpc::ServerUnaryReactor* ClientServiceImpl::AckFrame(grpc::CallbackServerContext* ctx, const v1::AckFrameRequest* req,
                                                      v1::AckFrameResponse*) {
  Caller caller;
  if (Status s = authenticate(*ctx, &caller); !s.ok()) return reply(ctx, std::move(s));
  if (Status s = authorize(req->job_id(), caller, "acknowledge frames of"); !s.ok()) return reply(ctx, std::move(s));
  return reply(ctx, coord_.ack_frame(req->job_id(), req->frame()));
}

grpc::ServerUnaryReactor* ClientServiceImpl::GetJob(grpc::CallbackServerContext* ctx, const v1::GetJobRequest* req,
                                                    v1::JobStatus* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return reply(ctx, std::move(s));
  if (Status s = farm::check_job_id(req->job_id()); !s.ok()) return reply(ctx, std::move(s));
  return reply(ctx, coord_.get_job(req->job_id(), resp));
}

grpc::ServerUnaryReactor* ClientServiceImpl::ListJobs(grpc::CallbackServerContext* ctx, const v1::ListJobsRequest*,
                                                      v1::ListJobsResponse* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return reply(ctx, std::move(s));
  coord_.list_jobs(resp);
  return reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* ClientServiceImpl::CancelJob(grpc::CallbackServerContext* ctx,
                                                       const v1::CancelJobRequest* req, v1::JobStatus* resp) {
  Caller caller;
  if (Status s = authenticate(*ctx, &caller); !s.ok()) return reply(ctx, std::move(s));
  if (Status s = authorize(req->job_id(), caller, "cancel"); !s.ok()) return reply(ctx, std::move(s));
  return reply(ctx, coord_.cancel(req->job_id(), resp, req->discard_undelivered()));
}

grpc::ServerUnaryReactor* ClientServiceImpl::SetJobPriority(grpc::CallbackServerContext* ctx,
                                                            const v1::SetJobPriorityRequest* req, v1::JobStatus* resp) {
  Caller caller;
  if (Status s = authenticate(*ctx, &caller); !s.ok()) return reply(ctx, std::move(s));
  if (Status s = authorize(req->job_id(), caller, "change the priority of"); !s.ok()) return reply(ctx, std::move(s));
  return reply(ctx, coord_.set_priority(req->job_id(), req->priority(), resp));
}

grpc::ServerUnaryReactor* ClientServiceImpl::ListWorkers(grpc::CallbackServerContext* ctx,
                                                         const v1::ListWorkersRequest*,
                                                         v1::ListWorkersResponse* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return reply(ctx, std::move(s));
  coord_.list_workers(resp);
  return reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* ClientServiceImpl::ListRayServers(grpc::CallbackServerContext* ctx,
                                                            const v1::ListRayServersRequest*,
                                                            v1::ListRayServersResponse* resp) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kClient); !s.ok()) return reply(ctx, std::move(s));
  coord_.ray_servers().list(resp);
  return reply(ctx, Status::OK);
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "worker_service.h"

#include <spdlog/spdlog.h>

#include <atomic>

#include "farm/bundle.h"
#include "stream_sink.h"

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

namespace {

constexpr size_t kChunkBytes = size_t(1) << 20;

// What a worker may say of itself. Its name goes into every tile it renders (stored, streamed to
// clients, shown by the monitor), so it is bounded like the tile's pixels are.
constexpr size_t kMaxWorkerNameBytes = 256;
constexpr size_t kMaxIsaBytes = 64;
constexpr size_t kMaxVersionBytes = 256;
constexpr int kMaxWorkerThreads = 4096;

// "" or what is wrong with a registration, naming the field, its value's size and the bound.
std::string check_register(const v1::Register& r) {
  const auto too_long = [](const char* field, const std::string& v, size_t max) -> std::string {
    if (v.size() <= max) return {};
    return fmt::format("register.{} is {} bytes, at most {}", field, v.size(), max);
  };
  for (std::string e : {too_long("name", r.name(), kMaxWorkerNameBytes),
                        too_long("embree_isa", r.embree_isa(), kMaxIsaBytes),
                        too_long("version", r.version(), kMaxVersionBytes)}) {
    if (!e.empty()) return e;
  }
  if (r.threads() > kMaxWorkerThreads) {
    return fmt::format("register.threads is {}, at most {}", r.threads(), kMaxWorkerThreads);
  }
  return {};
}

// One worker's session. Reads drive the scheduler through the coordinator; writes (welcome,
// assignments, revocations) come from the coordinator through the outbox.
class WorkerSession : public grpc::ServerBidiReactor<v1::WorkerMessage, v1::CoordinatorMessage> {
 public:
  using Sink = OutboxSink<WorkerSession, v1::CoordinatorMessage>;

  WorkerSession(Coordinator& c, std::string peer)
      : coord_(c), peer_(std::move(peer)), sink_(std::make_shared<Sink>(this)) {
    StartRead(&in_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {  // the worker closed its side, or the connection broke
      leave("disconnected");
      finish(Status::OK);
      return;
    }
    if (id_ == 0) {
      if (in_.msg_case() != v1::WorkerMessage::kRegister) {
        finish(Status(StatusCode::FAILED_PRECONDITION, "the first message of a worker session must be `register`"));
        return;
      }
      const auto& r = in_.register_();
      if (std::string e = check_register(r); !e.empty()) {
        spdlog::warn("worker registration from {} refused: {}", peer_, e);
        finish(Status(StatusCode::INVALID_ARGUMENT, e));
        return;
      }
      WorkerInfo info{r.name().empty() ? peer_ : r.name(), peer_, std::max(1, r.threads()), r.embree_isa(),
                      r.reads_spans()};
      id_ = coord_.register_worker(info, sink_, r.reads_assignment_batches());
    } else if (in_.msg_case() == v1::WorkerMessage::kRegister) {
      finish(Status(StatusCode::FAILED_PRECONDITION, "worker already registered on this stream"));
      return;
    } else {
      coord_.worker_message(id_, in_);
    }
    StartRead(&in_);
  }
  void OnWriteDone(bool ok) override { sink_->box.on_write_done(ok); }
  void OnCancel() override {
    leave("connection lost");
    finish(Status(StatusCode::CANCELLED, "session cancelled"));
  }
  void OnDone() override {
    leave("stream ended");
    sink_->box.on_done();
    delete this;
  }

 private:
  void leave(std::string_view reason) {
    if (id_ != 0 && !left_.exchange(true)) coord_.worker_gone(id_, reason);
  }
  void finish(Status s) {
    sink_->finish(std::move(s));
    sink_->pump();
  }

  Coordinator& coord_;
  std::string peer_;
  std::shared_ptr<Sink> sink_;
  v1::WorkerMessage in_;
  std::atomic<WorkerId> id_{0};  // 0 until registered (read by OnCancel on another thread)
  std::atomic<bool> left_{false};
};

class FetchReactor : public grpc::ServerWriteReactor<v1::BundleChunk> {
 public:
  FetchReactor(BundleStore& store, const std::string& sha) {
    auto bytes = store.read(sha);
    if (!bytes) {
      Finish(Status(StatusCode::NOT_FOUND, "bundle " + sha + " is not on this coordinator"));
      return;
    }
    bytes_ = std::move(*bytes);
    sha_ = sha;
    next();
  }
  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish(Status(StatusCode::UNAVAILABLE, "fetch interrupted"));
      return;
    }
    next();
  }
  void OnDone() override { delete this; }

 private:
  void next() {
    if (offset_ >= bytes_.size() && offset_ > 0) {
      Finish(Status::OK);
      return;
    }
    chunk_.Clear();
    if (offset_ == 0) chunk_.set_sha256(sha_);
    const size_t n = std::min(kChunkBytes, bytes_.size() - offset_);
    chunk_.set_data(bytes_.substr(offset_, n));
    offset_ += std::max<size_t>(n, 1);  // an empty bundle still sends one chunk
    StartWrite(&chunk_);
  }
  std::string bytes_, sha_;
  size_t offset_ = 0;
  v1::BundleChunk chunk_;
};

}  // namespace

grpc::ServerBidiReactor<v1::WorkerMessage, v1::CoordinatorMessage>* WorkerServiceImpl::Connect(
    grpc::CallbackServerContext* ctx) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kWorker); !s.ok()) {
    return new farm::Refused<grpc::ServerBidiReactor<v1::WorkerMessage, v1::CoordinatorMessage>>(std::move(s));
  }
  return new WorkerSession(coord_, ctx->peer());
}

grpc::ServerWriteReactor<v1::BundleChunk>* WorkerServiceImpl::FetchBundle(grpc::CallbackServerContext* ctx,
                                                                         const v1::FetchBundleRequest* req) {
  if (Status s = auth_.check(*ctx, farm::PeerRole::kWorker); !s.ok()) {
    return new farm::Refused<grpc::ServerWriteReactor<v1::BundleChunk>>(std::move(s));
  }
  return new FetchReactor(coord_.bundles(), req->sha256());
}

grpc::ServerUnaryReactor* WorkerServiceImpl::AnnounceRayServer(grpc::CallbackServerContext* ctx,
                                                               const v1::RayServerAnnouncement* req,
                                                               v1::RayServerAnnouncementAck* ack) {
  Status s = auth_.check(*ctx, farm::PeerRole::kWorker);
  if (!s.ok()) {
    // Said here too: the operator looking at the coordinator sees why a ray server is not listed.
    spdlog::warn("ray server announcement from {} refused: {}", ctx->peer(), s.error_message());
  } else {
    s = coord_.ray_servers().announce(*req, ctx->peer(), ack);
  }
  auto* r = ctx->DefaultReactor();
  r->Finish(std::move(s));
  return r;
}

}  // namespace tessera::server

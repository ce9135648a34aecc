// SPDX-License-Identifier: Apache-2.0
// The write side of a stream as the coordinator sees it (StreamSink), and the one adapter that puts
// it over a reactor's Outbox (OutboxSink): the coordinator queues messages without knowing the
// reactor types; each service's reactor owns an OutboxSink and writes what was queued.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>

#include "stream_outbox.h"

namespace tessera::server {

// Type-erased write side of a stream, so the coordinator does not depend on the reactor types.
template <class Msg>
class StreamSink {
 public:
  virtual ~StreamSink() = default;
  virtual void push(Msg m) = 0;
  // Queues a message built only when it is written (see stream_outbox.h).
  virtual void push_deferred(std::function<void(Msg*)> make) = 0;
  // Queues a shared payload (a tile's encoded bytes), built into messages by the stream's batch
  // builder (see stream_outbox.h); only streams that set one take these.
  virtual void push_shared(std::shared_ptr<const std::string> payload) = 0;
  virtual void finish(grpc::Status s) = 0;
  virtual void pump() = 0;
  virtual size_t queued() const = 0;  // messages not yet handed to gRPC
  // Watch streams: set (under the coordinator's mutex) while this stream's backlog holds its job
  // back; the stream calls Coordinator::watcher_drained once it has caught up.
  std::atomic<bool> throttled{false};
};

// A StreamSink that queues into the outbox of `Reactor`. The reactor forwards its OnWriteDone and
// OnDone to `box` (stream_outbox.h says why writes go through an outbox at all).
template <class Reactor, class Msg, class Wire = Msg>
struct OutboxSink : StreamSink<Msg> {
  explicit OutboxSink(Reactor* r) : box(r) {}
  void push(Msg m) override { box.push(std::move(m)); }
  void push_deferred(std::function<void(Msg*)> make) override { box.push_deferred(std::move(make)); }
  void push_shared(std::shared_ptr<const std::string> payload) override { box.push_shared(std::move(payload)); }
  void finish(grpc::Status s) override { box.finish(std::move(s)); }
  void pump() override { box.pump(); }
  size_t queued() const override { return box.queued(); }
  Outbox<Reactor, Msg, Wire> box;
};

}  // namespace tessera::server

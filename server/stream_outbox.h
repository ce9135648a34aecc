// SPDX-License-Identifier: Apache-2.0
// The write side of a server-streaming callback RPC: a queue of messages written one at a time,
// then Finish. gRPC allows one outstanding write per stream, and reactions may run inline on the
// thread that starts an operation, so StartWrite/Finish are only ever called here, with no lock
// held; callers queue under their own locks and call pump() after releasing them.
//
// Lifetime: the reactor owns a shared_ptr to its outbox and calls on_done() from OnDone() before
// deleting itself; others (the coordinator) may keep the outbox longer and push into the void.
//
// A message can also be queued deferred: a function that builds it when its turn to be written
// comes. A finished tile then waits in the queue as a reference to the coordinator's one encoded
// copy (a few dozen bytes) rather than as a parsed copy per stream (its full size).
//
// Shared payloads (push_shared: a tile's encoded bytes) are built into messages by the stream's
// batch builder (set_batching), several at a time: every shared payload queued back to back,
// up to a count and a byte bound, goes into one message when its turn comes. A stream whose
// writes keep up sends one a message; one that falls behind catches up in fewer, fuller
// messages, and each message costs the coordinator a hand-off between gRPC's threads and a
// system call or two, whatever its size.
//
// What is written (`Wire`) is the message type itself, or grpc::ByteBuffer for a stream that
// sends bytes it did not serialize (a raw method): queued messages are then serialized when their
// turn comes, and the batch builder makes the bytes directly (watch_wire.h: tiles go out as the
// slices the coordinator stores, not copied).
#pragma once

#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/codegen/proto_utils.h>  // SerializationTraits of protobuf messages

#include <algorithm>
#include <atomic>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

namespace tessera::server {

template <class Reactor, class Msg, class Wire = Msg>
class Outbox {
 public:
  using Deferred = std::function<void(Msg*)>;  // fills a cleared message
  using Shared = std::shared_ptr<const std::string>;
  // Fills a cleared message with `n` shared payloads (n >= 1, as many as the bounds allowed).
  using BatchBuilder = std::function<void(Wire*, const Shared* payloads, size_t n)>;

  explicit Outbox(Reactor* reactor) : reactor_(reactor) {}

  // Queues a message; call pump() afterwards (outside other locks) to get it moving.
  void push(Msg msg) { enqueue(Item(std::in_place_index<0>, std::move(msg))); }
  void push_deferred(Deferred make) { enqueue(Item(std::in_place_index<1>, std::move(make))); }
  // Queues a shared payload for the batch builder; set_batching must have been called.
  void push_shared(Shared payload) { enqueue(Item(std::in_place_index<2>, std::move(payload))); }
  // How shared payloads become messages: at most `max_items` and, past the first, `max_bytes`
  // of payload a message. Call before anything is queued.
  void set_batching(BatchBuilder build, size_t max_items, size_t max_bytes) {
    std::lock_guard lock(mu_);
    build_ = std::move(build);
    max_items_ = std::max<size_t>(1, max_items);
    max_bytes_ = max_bytes;
  }
  // Messages queued and not yet handed to gRPC (the flow-control measure; no lock needed).
  size_t queued() const { return queued_.load(std::memory_order_relaxed); }
  // Finishes the stream with `status` once the queued messages are written (the first status
  // requested wins).
  void finish(grpc::Status status) {
    std::lock_guard lock(mu_);
    if (finish_requested_) return;
    finish_requested_ = true;
    status_ = std::move(status);
  }
  void pump() {
    std::unique_lock lock(mu_);
    if (!reactor_ || writing_ || finish_called_) return;
    if (!queue_.empty()) {
      Item& front = queue_.front();
      if (front.index() == 0) {
        set_current(std::move(std::get<0>(front)));
        queue_.pop_front();
      } else if (front.index() == 1) {
        Msg m;
        std::get<1>(front)(&m);
        set_current(std::move(m));
        queue_.pop_front();
      } else {
        // The run of shared payloads at the front, within the bounds.
        batch_.clear();
        size_t bytes = 0;
        while (!queue_.empty() && queue_.front().index() == 2 && batch_.size() < max_items_) {
          const Shared& p = std::get<2>(queue_.front());
          if (!batch_.empty() && bytes + p->size() > max_bytes_) break;
          bytes += p->size();
          batch_.push_back(p);
          queue_.pop_front();
        }
        current_.Clear();
        build_(&current_, batch_.data(), batch_.size());
        batch_.clear();
      }
      queued_.store(queue_.size(), std::memory_order_relaxed);
      writing_ = true;
      Reactor* r = reactor_;
      lock.unlock();
      r->StartWrite(&current_);
      return;
    }
    if (finish_requested_) {
      finish_called_ = true;
      Reactor* r = reactor_;
      grpc::Status s = status_;
      lock.unlock();
      r->Finish(s);
    }
  }
  // From the reactor's OnWriteDone.
  void on_write_done(bool ok) {
    {
      std::lock_guard lock(mu_);
      writing_ = false;
      if (!ok) {  // the stream is broken: nothing more will get through
        queue_.clear();
        queued_.store(0, std::memory_order_relaxed);
        if (!finish_requested_) {
          finish_requested_ = true;
          status_ = grpc::Status(grpc::StatusCode::UNAVAILABLE, "stream broken");
        }
      }
    }
    pump();
  }
  // From the reactor's OnDone: the reactor is about to be deleted.
  void on_done() {
    std::lock_guard lock(mu_);
    reactor_ = nullptr;
    queue_.clear();
    queued_.store(0, std::memory_order_relaxed);
  }
  bool finishing() {
    std::lock_guard lock(mu_);
    return finish_requested_;
  }

 private:
  using Item = std::variant<Msg, Deferred, Shared>;
  void set_current(Msg&& m) {
    if constexpr (std::is_same_v<Msg, Wire>) {
      current_ = std::move(m);
    } else {
      current_.Clear();
      bool own = false;
      grpc::SerializationTraits<Msg>::Serialize(m, &current_, &own);
    }
  }
  void enqueue(Item item) {
    std::lock_guard lock(mu_);
    if (finish_requested_ || !reactor_) return;
    queue_.push_back(std::move(item));
    queued_.store(queue_.size(), std::memory_order_relaxed);
  }

  std::mutex mu_;
  Reactor* reactor_;
  std::deque<Item> queue_;
  std::atomic<size_t> queued_{0};
  Wire current_;
  BatchBuilder build_;
  size_t max_items_ = 1;
  size_t max_bytes_ = 0;
  std::vector<Shared> batch_;
  bool writing_ = false;
  bool finish_requested_ = false;
  bool finish_called_ = false;
  grpc::Status status_;
};

}  // namespace tessera::server

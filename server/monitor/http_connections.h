// SPDX-License-Identifier: Apache-2.0
// The HTTP side's connections (cpp-httplib serves each on a thread of a pool) with deadlines per
// request, not per byte, so that slow or many clients cannot starve the others.
//
// cpp-httplib 0.11 (Debian bookworm) times out each read on its own: a client that sends one
// header byte a second holds its thread for as long as it likes, and 16 such clients held the
// whole pool (/metrics and the monitor timed out for everyone). This task queue is the pool
// cpp-httplib runs connections on (`Server::new_task_queue`), and it watches them:
//   - a request's head must be complete within `header_deadline` of the connection's accept or
//     of the previous response (request_read() marks it, from a pre-routing handler);
//   - a request must be answered, body read and response written, within `response_deadline`
//     (response_written() marks it, from the logger);
//   - a request (its head, and its body, which http_listener.h bounds before it is read) may
//     bring at most `max_request_bytes` from the previous response (or the accept) on: cpp-httplib
//     reads a request line or a header line until its newline however long it is, and any number
//     of header lines, so an endless head from an unauthenticated client used to grow the
//     coordinator by hundreds of MiB within the head's deadline. The kernel's count of the bytes
//     the connection received (TCP_INFO) is compared every `tick`;
//   - past any of these, the connection is shut down (the socket, through a duplicate of the
//     descriptor, so a number reused by then is never touched) and its thread is free;
//   - at most `max_connections` at once and `max_per_peer` from one address; beyond, a new
//     connection is closed at once;
//   - a request refused before its body was read (http_listener.h) ends its connection once the
//     answer is written (close_after_response()): the connection is shut down for writing, what
//     the client still sends is read and dropped for at most `linger` (time for it to read the
//     answer: closing on unread bytes resets the connection, which can erase the answer at the
//     client), then shut down whole.
// The pool has many threads (a waiting thread costs only its stack): a slow client holds one for
// at most a deadline, and needs a connection, counted, to do it.
//
// cpp-httplib does not say which socket a task serves. It accepts on the listener thread and
// queues the connection's task right after, so http_connections.cpp defines accept() (the
// library's only caller; gRPC uses accept4) to note the descriptor it returns on that thread.
#pragma once

#include <httplib.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace tessera::server {

class HttpConnections : public httplib::TaskQueue {
 public:
  struct Options {
    size_t threads = 128;
    size_t max_connections = 512;
    size_t max_per_peer = 64;
    std::chrono::milliseconds header_deadline{10000};
    std::chrono::milliseconds response_deadline{30000};
    std::chrono::milliseconds linger{1000};
    uint64_t max_request_bytes = 64 << 10;
    std::chrono::milliseconds tick{100};
  };

  struct Connection;  // one accepted connection (http_connections.cpp)

  explicit HttpConnections(Options options);
  ~HttpConnections() override;

  void enqueue(std::function<void()> fn) override;
  void shutdown() override;

  // On a connection's thread: its request's head is in (pre-routing), or its response is written
  // and it waits for the next request (logger).
  static void request_read();
  static void response_written();
  // On a connection's thread, before its answer is written: end the connection after it.
  static void close_after_response();

 private:
  void run();
  void watch();
  // Shuts the connection down after its answer: see close_after_response().
  void linger_close(Connection& c) const;
  void end(const std::shared_ptr<Connection>& c);

  const Options options_;
  std::mutex mu_;
  std::condition_variable cv_;        // pool threads: a connection is queued, or stop
  std::condition_variable watch_cv_;  // the watchdog: stop
  std::deque<std::pair<std::shared_ptr<Connection>, std::function<void()>>> queue_;
  std::map<Connection*, std::shared_ptr<Connection>> live_;
  std::map<std::string, size_t> per_peer_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
  std::thread watchdog_;
};

}  // namespace tessera::server

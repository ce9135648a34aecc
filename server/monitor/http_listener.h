// SPDX-License-Identifier: Apache-2.0
// The coordinator's HTTP side (`tessera-server --http-listen HOST:PORT`): the web monitor, its
// JSON API and /metrics. cpp-httplib (Debian's libcpp-httplib, built with OpenSSL) serves it:
// plain HTTP, or HTTPS with the certificate and key the gRPC side uses when TLS is configured.
// With a client CA (mutual TLS), HTTPS asks for and verifies client certificates too, as gRPC does.
//
// Nothing of a request's body is read before its head has passed two checks, so that a peer
// costs nothing before it is authenticated and little after (cpp-httplib 0.11 reads a body whole
// into memory before any handler runs: four unauthenticated 200 MiB POSTs took the coordinator to
// 1,095 MiB, and one of 1.5 GiB ended it with std::bad_alloc):
//   - the gate (set_gate; the monitor's: a client token on every route but the page's files);
//   - the body's length: declared (Content-Length; a chunked body, or a POST that declares none,
//     which cpp-httplib would read until the connection closes, is refused 411) and at most
//     kMaxBodyBytes (413, naming the limit).
// A request refused with a body pending gets its answer, and then the connection is closed
// (HttpConnections::close_after_response): the unread body is never taken for a next request.
// The head itself is bounded by the bytes a request may bring (http_connections.h).
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace httplib {
class Server;
struct Request;
struct Response;
}

namespace tessera::server {

struct HttpTls {
  std::string cert, key, client_ca;  // files; cert empty: plain HTTP
};

class HttpListener {
 public:
  // Throws std::runtime_error naming the problem for a malformed address or unreadable TLS files.
  HttpListener(const std::string& address, const HttpTls& tls);
  ~HttpListener();  // stops
  HttpListener(const HttpListener&) = delete;
  HttpListener& operator=(const HttpListener&) = delete;

  // The largest request body any route takes, with room to spare: the monitor's largest is an
  // action's JSON, {"priority":-2147483648}, 24 bytes.
  static constexpr size_t kMaxBodyBytes = 4096;
  // Answers a request from its head alone (returning true) to refuse it before its body is read.
  using Gate = std::function<bool(const httplib::Request&, httplib::Response&)>;
  // Set before start().
  void set_gate(Gate gate) { gate_ = std::move(gate); }

  httplib::Server& server() { return *server_; }
  bool tls() const { return tls_; }
  // Binds (port 0 picks a free one) and serves on a thread of its own. Returns the port; throws
  // std::runtime_error when the address cannot be bound.
  int start();
  void stop();

 private:
  std::string host_;
  int port_ = 0;
  bool tls_ = false;
  std::unique_ptr<httplib::Server> server_;
  Gate gate_;
  std::thread thread_;
};

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// The coordinator's HTTP side (`tessera-server --http-listen HOST:PORT`): the web monitor, its
// JSON API and /metrics. cpp-httplib (Debian's libcpp-httplib, built with OpenSSL) serves it:
// plain HTTP, or HTTPS with the certificate and key the gRPC side uses when TLS is configured.
// With a client CA (mutual TLS), HTTPS asks for and verifies client certificates too, as gRPC does.
#pragma once

#include <memory>
#include <string>
#include <thread>

namespace httplib {
class Server;
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
  std::thread thread_;
};

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "http_listener.h"

#include <httplib.h>

#include <nlohmann/json.hpp>

#include "http_connections.h"

#include <fstream>
#include <stdexcept>

namespace tessera::server {

namespace {

void require_readable(const std::string& path, const char* what) {
  if (!std::ifstream(path)) throw std::runtime_error(std::string("--http-listen: cannot read the TLS ") + what + " " + path);
}

bool refuse(httplib::Response& res, int status, const std::string& why) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(nlohmann::json{{"error", why}}.dump(), "application/json");
  return true;
}

// Methods whose body cpp-httplib reads (until the connection closes when no length is declared).
bool reads_body(const httplib::Request& req) {
  return req.method == "POST" || req.method == "PUT" || req.method == "PATCH" || req.method == "DELETE" ||
         req.method == "PRI";
}

// Whether bytes of a body may follow the head: a refusal then closes the connection.
bool body_may_follow(const httplib::Request& req) {
  return reads_body(req) || req.has_header("Transfer-Encoding") ||
         (req.has_header("Content-Length") && req.get_header_value("Content-Length") != "0");
}

// Refuses (true) a body whose length is not declared once, or is over the limit, from the head.
bool refuse_body(const httplib::Request& req, httplib::Response& res) {
  const std::string limit = std::to_string(HttpListener::kMaxBodyBytes) + " bytes";
  if (req.has_header("Transfer-Encoding")) {
    return refuse(res, 411, "request bodies must declare their Content-Length (at most " + limit + "); chunked "
                            "bodies are not taken");
  }
  if (!req.has_header("Content-Length")) {
    return reads_body(req) && refuse(res, 411, "a " + req.method + " must declare its body's Content-Length (0 for "
                                               "none, at most " + limit + ")");
  }
  const std::string declared = req.get_header_value("Content-Length");
  if (req.get_header_value_count("Content-Length") != 1 || declared.empty() || declared.size() > 19 ||
      declared.find_first_not_of("0123456789") != std::string::npos) {
    return refuse(res, 400, "Content-Length must be one decimal number");
  }
  const uint64_t length = std::stoull(declared);
  if (length <= HttpListener::kMaxBodyBytes) return false;
  return refuse(res, 413, "the request body is " + declared + " bytes, over this monitor's limit " + limit);
}

}  // namespace

HttpListener::HttpListener(const std::string& address, const HttpTls& tls) {
  const auto colon = address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == address.size()) {
    throw std::runtime_error("--http-listen '" + address + "': expected HOST:PORT, e.g. 0.0.0.0:8080");
  }
  host_ = address.substr(0, colon);
  if (host_.size() > 2 && host_.front() == '[' && host_.back() == ']') host_ = host_.substr(1, host_.size() - 2);
  try {
    size_t used = 0;
    port_ = std::stoi(address.substr(colon + 1), &used);
    if (used != address.size() - colon - 1 || port_ < 0 || port_ > 65535) throw std::out_of_range("port");
  } catch (const std::exception&) {
    throw std::runtime_error("--http-listen '" + address + "': the port must be a number in [0, 65535]");
  }
  if (tls.cert.empty()) {
    server_ = std::make_unique<httplib::Server>();
  } else {
    require_readable(tls.cert, "certificate");
    require_readable(tls.key, "key");
    if (!tls.client_ca.empty()) require_readable(tls.client_ca, "client CA");
    auto ssl = std::make_unique<httplib::SSLServer>(tls.cert.c_str(), tls.key.c_str(),
                                                    tls.client_ca.empty() ? nullptr : tls.client_ca.c_str());
    if (!ssl->is_valid()) {
      throw std::runtime_error("--http-listen: the TLS certificate " + tls.cert + " and key " + tls.key +
                               " were refused by OpenSSL (not PEM, or not a pair)");
    }
    server_ = std::move(ssl);
    tls_ = true;
  }
  // cpp-httplib serves each connection on a thread of a fixed pool, also while a kept-alive
  // connection waits for its next request. Pages poll once a second: a short keep-alive still
  // reuses the connection between two polls, and a browser that went away frees its thread soon.
  server_->set_keep_alive_timeout(2);
  server_->set_read_timeout(10, 0);
  server_->set_write_timeout(10, 0);
  // Deadlines per request, caps on connections (http_connections.h): a slow or silent client
  // holds a thread for seconds, not for as long as it likes.
  server_->new_task_queue = [] { return new HttpConnections(HttpConnections::Options{}); };
  // Bodies (the header): the head is checked before any byte of the body is read; a body that
  // slips past (none should) is still bounded by cpp-httplib's own limit.
  server_->set_payload_max_length(kMaxBodyBytes);
  server_->set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    HttpConnections::request_read();
    if (!(gate_ && gate_(req, res)) && !refuse_body(req, res)) return httplib::Server::HandlerResponse::Unhandled;
    if (body_may_follow(req)) HttpConnections::close_after_response();
    return httplib::Server::HandlerResponse::Handled;
  });
  server_->set_logger([](const httplib::Request&, const httplib::Response&) { HttpConnections::response_written(); });
}

HttpListener::~HttpListener() { stop(); }

int HttpListener::start() {
  const int port = port_ == 0 ? server_->bind_to_any_port(host_) : (server_->bind_to_port(host_, port_) ? port_ : -1);
  if (port <= 0) {
    throw std::runtime_error("--http-listen: cannot listen on " + host_ + ":" + std::to_string(port_) +
                             " (address in use or not local?)");
  }
  thread_ = std::thread([this] { server_->listen_after_bind(); });
  return port;
}

void HttpListener::stop() {
  if (!thread_.joinable()) return;
  server_->stop();
  thread_.join();
}

}  // namespace tessera::server

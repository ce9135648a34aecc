// SPDX-License-Identifier: Apache-2.0
#include "monitor_routes.h"

#include <httplib.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <spdlog/spdlog.h>

#include <nlohmann/json.hpp>

#include "farm_control.h"
#include "http_listener.h"
#include "job_access.h"
#include "metrics/farm_metrics.h"
#include "monitor_feed.h"
#include "web_assets.h"

namespace tessera::server {

namespace {

using grpc::Status;
using grpc::StatusCode;
using nlohmann::json;

constexpr const char* kJobRoute = R"(/api/jobs/([0-9A-Za-z_.-]{1,128}))";

int http_status(StatusCode c) {
  switch (c) {
    case StatusCode::OK: return 200;
    case StatusCode::UNAUTHENTICATED: return 401;
    case StatusCode::PERMISSION_DENIED: return 403;
    case StatusCode::NOT_FOUND: return 404;
    case StatusCode::INVALID_ARGUMENT: return 400;
    case StatusCode::FAILED_PRECONDITION: return 409;
    case StatusCode::RESOURCE_EXHAUSTED: return 429;
    case StatusCode::UNAVAILABLE: return 503;
    default: return 500;
  }
}

void send_json(httplib::Response& res, int code, const json& body) {
  res.status = code;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body.dump(), "application/json");
}

void send_error(httplib::Response& res, const Status& s) {
  if (s.error_code() == StatusCode::UNAUTHENTICATED) res.set_header("WWW-Authenticate", "Bearer");
  send_json(res, http_status(s.error_code()), json{{"error", s.error_message()}});
}

// "cn:NAME" of a verified TLS client certificate (mutual TLS), as farm::client_identity() in gRPC.
std::string certificate_identity(const httplib::Request& req) {
  if (!req.ssl) return {};
  X509* cert = SSL_get1_peer_certificate(req.ssl);
  if (!cert) return {};
  char cn[256] = {};
  const int n = X509_NAME_get_text_by_NID(X509_get_subject_name(cert), NID_commonName, cn, sizeof cn);
  X509_free(cert);
  return n > 0 ? "cn:" + std::string(cn, size_t(n)) : std::string();
}

std::optional<int> int_param(const httplib::Request& req, const char* name, Status* error) {
  if (!req.has_param(name)) return std::nullopt;
  const std::string v = req.get_param_value(name);
  try {
    size_t used = 0;
    const int n = std::stoi(v, &used);
    if (used == v.size()) return n;
  } catch (const std::exception&) {
  }
  *error = Status(StatusCode::INVALID_ARGUMENT, std::string(name) + ": '" + v + "' is not an integer");
  return std::nullopt;
}

// Actions change state: they must come from the page's fetch() (a JSON body), not from a form
// another site posts into a browser that can reach the coordinator (forms cannot send JSON
// without a CORS preflight, which this server never grants).
Status json_body(const httplib::Request& req, json* body) {
  if (req.get_header_value("Content-Type").rfind("application/json", 0) != 0) {
    return Status(StatusCode::INVALID_ARGUMENT, "actions take a JSON body (Content-Type: application/json)");
  }
  *body = json::parse(req.body.empty() ? "{}" : req.body, nullptr, false);
  if (body->is_discarded() || !body->is_object()) return Status(StatusCode::INVALID_ARGUMENT, "the body is not a JSON object");
  return Status::OK;
}

void send_page(std::string_view name, httplib::Response& res) {
  const WebAsset* a = web_asset(name);
  if (!a) {
    res.status = 404;
    res.set_content("no such file", "text/plain");
    return;
  }
  res.set_content(std::string(a->bytes), std::string(a->content_type).c_str());
}

// The handlers, sharing a copy of the routes' references and settings: they outlive install().
class Handlers {
 public:
  explicit Handlers(const MonitorRoutes& routes) : self_(routes) {}

  void whoami(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    if (Status s = authenticate(req, &caller); !s.ok()) return send_error(res, s);
    send_json(res, 200,
              {{"identity", caller.identity}, {"admin", caller.admin}, {"token_required", !self_.auth.open(farm::PeerRole::kClient)}});
  }

  void farm(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    if (Status s = authenticate(req, &caller); !s.ok()) return send_error(res, s);
    send_json(res, 200, self_.feed.farm());
  }

  void job(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    const auto id = job_request(req, res, "watch", &caller);
    if (!id) return;
    Status bad;
    const auto frame = int_param(req, "frame", &bad);
    if (!bad.ok()) return send_error(res, bad);
    auto j = self_.feed.job(*id, frame);
    if (!j) return send_error(res, Status(StatusCode::NOT_FOUND, "job " + *id + " is no longer in the coordinator's memory"));
    send_json(res, 200, *j);
  }

  void preview(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    const auto id = job_request(req, res, "watch", &caller);
    if (!id) return;
    Status bad;
    const auto frame = int_param(req, "frame", &bad);
    color::ToneMapSettings tonemap;
    if (req.has_param("tonemap")) {
      const auto op = color::parse_tonemap(req.get_param_value("tonemap"));
      if (!op) bad = Status(StatusCode::INVALID_ARGUMENT, "tonemap: '" + req.get_param_value("tonemap") +
                                                              "' is not clamp, reinhard, aces or pbr-neutral");
      else tonemap.op = *op;
    }
    if (const auto ev = int_param(req, "exposure", &bad)) tonemap.exposure_ev = float(*ev);
    if (!bad.ok()) return send_error(res, bad);
    std::optional<std::string> png;
    try {
      png = self_.feed.preview(*id, frame, tonemap);
    } catch (const std::exception& e) {
      return send_error(res, Status(StatusCode::INTERNAL, std::string("cannot encode the preview: ") + e.what()));
    }
    if (!png) return send_error(res, Status(StatusCode::NOT_FOUND, "no finished tile of that frame of job " + *id + " in memory"));
    res.set_header("Cache-Control", "no-store");
    res.set_content(std::move(*png), "image/png");
  }

  void cancel(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    json body;
    const auto id = job_request(req, res, "cancel", &caller);
    if (!id) return;
    if (Status s = json_body(req, &body); !s.ok()) return send_error(res, s);
    tessera::v1::JobStatus status;
    if (Status s = self_.coordinator.cancel(*id, &status); !s.ok()) return send_error(res, s);
    spdlog::info("monitor: {} cancelled job {}", caller.identity, *id);
    send_json(res, 200, {{"id", *id}, {"state", "cancelled"}});
  }

  void priority(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    json body;
    const auto id = job_request(req, res, "change the priority of", &caller);
    if (!id) return;
    if (Status s = json_body(req, &body); !s.ok()) return send_error(res, s);
    if (!body.contains("priority") || !body["priority"].is_number_integer()) {
      return send_error(res, Status(StatusCode::INVALID_ARGUMENT, "priority: an integer is required, e.g. {\"priority\": 5}"));
    }
    const int64_t p = body["priority"].get<int64_t>();
    if (p < INT32_MIN || p > INT32_MAX) {
      return send_error(res, Status(StatusCode::INVALID_ARGUMENT, "priority: " + std::to_string(p) + " is out of range"));
    }
    tessera::v1::JobStatus status;
    if (Status s = self_.coordinator.set_priority(*id, int(p), &status); !s.ok()) return send_error(res, s);
    spdlog::info("monitor: {} set the priority of job {} to {}", caller.identity, *id, p);
    send_json(res, 200, {{"id", *id}, {"priority", status.priority()}});
  }

  // The listener's gate: every request but one for the page's own files shows a valid token in
  // its head, or is answered 401 before its body is read.
  bool refuse_unauthenticated(const httplib::Request& req, httplib::Response& res) const {
    const bool page_file = req.path == "/" || req.path.rfind("/static/", 0) == 0;
    if ((req.method == "GET" || req.method == "HEAD") && page_file) return false;
    Caller caller;
    const Status s = authenticate(req, &caller);
    if (s.ok()) return false;
    send_error(res, s);
    return true;
  }

  void metrics(const httplib::Request& req, httplib::Response& res) const {
    Caller caller;
    if (Status s = authenticate(req, &caller); !s.ok()) return send_error(res, s);
    res.set_content(self_.metrics->scrape(), "text/plain; version=0.0.4; charset=utf-8");
  }

 private:
  // Who is calling, as ClientServiceImpl::authenticate decides it.
  Status authenticate(const httplib::Request& req, Caller* caller) const {
    std::optional<std::string_view> header;
    const std::string value = req.get_header_value("Authorization");
    if (req.has_header("Authorization")) header = value;
    std::string token_name;
    Status s = self_.auth.check_authorization(header, farm::PeerRole::kClient, &token_name);
    if (!s.ok()) return s;
    caller->identity = certificate_identity(req);
    if (caller->identity.empty() && !token_name.empty()) caller->identity = "token:" + token_name;
    if (caller->identity.empty()) {
      caller->identity = req.remote_addr.find(':') == std::string::npos ? "ipv4:" + req.remote_addr
                                                                         : "ipv6:[" + req.remote_addr + "]";
    }
    caller->admin = self_.admins.count(caller->identity) > 0;
    return s;
  }

  Status authorize(const std::string& job, const Caller& caller, const char* action) const {
    const std::optional<std::string> owner = self_.coordinator.job_owner(job);
    if (!owner) return Status(StatusCode::NOT_FOUND, "no job '" + job + "' on this coordinator");
    Status s = check_job_access(job, *owner, caller, action);
    if (!s.ok()) spdlog::warn("monitor: {} refused: {}", caller.identity, s.error_message());
    return s;
  }

  // The caller may do `action` to the job the route names: returns its id, or nothing after
  // answering with the refusal.
  std::optional<std::string> job_request(const httplib::Request& req, httplib::Response& res, const char* action,
                                         Caller* caller) const {
    const std::string id = req.matches[1];
    Status s = authenticate(req, caller);
    if (s.ok()) s = authorize(id, *caller, action);
    if (s.ok()) return id;
    send_error(res, s);
    return std::nullopt;
  }

  const MonitorRoutes self_;
};

}  // namespace

void MonitorRoutes::install(HttpListener& listener) const {
  const auto h = std::make_shared<const Handlers>(*this);
  listener.set_gate(
      [h](const httplib::Request& req, httplib::Response& res) { return h->refuse_unauthenticated(req, res); });
  httplib::Server& server = listener.server();
  using Handler = void (Handlers::*)(const httplib::Request&, httplib::Response&) const;
  const auto bind = [h](Handler f) {
    return [h, f](const httplib::Request& req, httplib::Response& res) { ((*h).*f)(req, res); };
  };

  server.set_post_routing_handler([](const httplib::Request&, httplib::Response& res) {
    res.set_header("X-Content-Type-Options", "nosniff");
    res.set_header("Content-Security-Policy", "default-src 'self'; img-src 'self' blob: data:; frame-ancestors 'none'");
  });
  server.Get("/", [](const httplib::Request&, httplib::Response& res) { send_page("index.html", res); });
  server.Get(R"(/static/([A-Za-z0-9_.-]+))",
             [](const httplib::Request& req, httplib::Response& res) { send_page(req.matches[1].str(), res); });
  server.Get("/api/whoami", bind(&Handlers::whoami));
  server.Get("/api/farm", bind(&Handlers::farm));
  server.Get(kJobRoute, bind(&Handlers::job));
  server.Get(std::string(kJobRoute) + "/preview.png", bind(&Handlers::preview));
  server.Post(std::string(kJobRoute) + "/cancel", bind(&Handlers::cancel));
  server.Post(std::string(kJobRoute) + "/priority", bind(&Handlers::priority));
  if (metrics) server.Get("/metrics", bind(&Handlers::metrics));
}

}  // namespace tessera::server

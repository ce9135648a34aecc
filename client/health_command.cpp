// `tessera health`: asks a coordinator's standard gRPC health service (grpc.health.v1.Health,
// enabled in tessera-server) whether it is serving. Container health checks and probes run it,
// so it prints one line and answers with its exit code only: 0 serving, 1 anything else
// (unreachable, not serving, unknown service). Docker reserves exit code 2 in HEALTHCHECK, so
// no failure here uses it.
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "commands.h"
#include "farm/channel.h"
#include "farm_client.h"
#include "farm_command.h"
#include "grpc/health/v1/health.grpc.pb.h"

namespace tessera::cli {

namespace {

namespace health = grpc::health::v1;

struct HealthArgs {
  std::string coordinator;
  SecurityFlags security;
  std::string service;  // "" = the server as a whole
  double timeout_s = 5;
  bool quiet = false;
};

const char* status_name(health::HealthCheckResponse::ServingStatus s) {
  switch (s) {
    case health::HealthCheckResponse::SERVING: return "SERVING";
    case health::HealthCheckResponse::NOT_SERVING: return "NOT_SERVING";
    case health::HealthCheckResponse::SERVICE_UNKNOWN: return "SERVICE_UNKNOWN";
    default: return "UNKNOWN";
  }
}

int run_health(const HealthArgs& a) {
  const std::string address = resolve_coordinator(a.coordinator);
  // The same channel and credentials every other command uses (TLS, token), so a probe sees
  // the coordinator exactly as clients do.
  std::shared_ptr<grpc::Channel> channel;
  try {
    channel = farm::make_coordinator_channel(address, resolve_security(a.security));
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "tessera health: %s\n", e.what());
    return 1;
  }
  auto stub = health::Health::NewStub(channel);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(a.timeout_s * 1000)));
  health::HealthCheckRequest req;
  req.set_service(a.service);
  health::HealthCheckResponse resp;
  const grpc::Status s = stub->Check(&ctx, req, &resp);
  const std::string what = a.service.empty() ? "coordinator" : "service '" + a.service + "'";
  if (!s.ok()) {
    if (s.error_code() == grpc::StatusCode::NOT_FOUND) {
      std::fprintf(stderr, "tessera health: %s: unknown to the coordinator at %s\n", what.c_str(), address.c_str());
    } else if (s.error_code() == grpc::StatusCode::UNIMPLEMENTED) {
      std::fprintf(stderr, "tessera health: %s does not serve grpc.health.v1.Health\n", address.c_str());
    } else {
      std::fprintf(stderr, "tessera health: cannot reach the coordinator at %s within %.1f s: %s\n", address.c_str(),
                   a.timeout_s, s.error_message().c_str());
    }
    return 1;
  }
  const bool serving = resp.status() == health::HealthCheckResponse::SERVING;
  if (!a.quiet || !serving) {
    std::fprintf(serving ? stdout : stderr, "%s %s: %s\n", what.c_str(), address.c_str(), status_name(resp.status()));
  }
  return serving ? 0 : 1;
}

}  // namespace

void register_health_command(CLI::App& app) {
  auto a = std::make_shared<HealthArgs>();
  CLI::App* cmd = app.add_subcommand(
      "health", "Ask a coordinator's gRPC health service whether it is serving (exit 0 yes, 1 no)");
  add_coordinator_option(cmd, &a->coordinator, &a->security);
  cmd->add_option("--service", a->service, "Service name to ask about (default: the whole server)");
  cmd->add_option("--timeout", a->timeout_s, "Seconds to wait for an answer")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", a->quiet, "Print nothing when serving");
  cmd->callback([a] {
    const int rc = run_health(*a);
    if (rc != 0) throw CLI::RuntimeError(rc);
  });
}

}  // namespace tessera::cli

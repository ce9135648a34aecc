// SPDX-License-Identifier: Apache-2.0
// `tessera health`: asks a coordinator's standard gRPC health service (grpc.health.v1.Health,
// enabled in tessera-server) whether it is serving. Container health checks and probes run it,
// so it prints one line and answers with its exit code only: 0 serving, 1 anything else
// (unreachable, not serving, unknown service). Docker reserves exit code 2 in HEALTHCHECK, so
// no failure here uses it.
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "command_error.h"
#include "commands.h"
#include "farm/channel.h"
#include "farm/farm_error.h"
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
  } catch (const farm::FarmError& e) {  // an unreadable token or certificate file
    throw CommandError{kExitFailure, e.what()};
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
  if (s.error_code() == grpc::StatusCode::NOT_FOUND) {
    throw CommandError{kExitFailure, what + ": unknown to the coordinator at " + address};
  }
  if (s.error_code() == grpc::StatusCode::UNIMPLEMENTED) {
    throw CommandError{kExitFailure, address + " does not serve grpc.health.v1.Health"};
  }
  if (!s.ok()) {
    char within[32];
    std::snprintf(within, sizeof within, "%.1f", a.timeout_s);  // as printf's %.1f
    throw CommandError{kExitFailure, "cannot reach the coordinator at " + address + " within " + within + " s: " +
                                         s.error_message()};
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
  cmd->callback([a] { guarded("health", [&] { return run_health(*a); }); });
}

}  // namespace tessera::cli

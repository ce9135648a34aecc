// SPDX-License-Identifier: Apache-2.0
#include "farm_command.h"

#include "farm/farm_error.h"

namespace tessera::cli {

CommandError job_error(const FarmClient& client, const grpc::Status& s, const std::string& what) {
  return CommandError{s.error_code() == grpc::StatusCode::NOT_FOUND ? kExitBadInput : kExitFailure,
                      client.describe(s, what)};
}

FarmClient connect(const std::string& coordinator, const SecurityFlags& flags) {
  try {
    return FarmClient(resolve_coordinator(coordinator), resolve_security(flags));
  } catch (const farm::FarmError& e) {  // an unreadable token or certificate file
    throw CommandError{kExitBadInput, e.what()};
  }
}

tessera::v1::JobStatus get_job(FarmClient& client, const std::string& job) {
  tessera::v1::GetJobRequest req;
  req.set_job_id(job);
  tessera::v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().GetJob(ctx.get(), req, &st);
  if (!s.ok()) {
    throw job_error(client, s, "looking up job " + job);
  }
  return st;
}

void add_coordinator_option(CLI::App* cmd, std::string* target, SecurityFlags* security) {
  cmd->add_option("--coordinator", *target,
                  std::string("Coordinator HOST:PORT (default: $TESSERA_COORDINATOR, else ") +
                      farm::kDefaultCoordinator + ")");
  add_security_flags(cmd, security);
}

void add_security_flags(CLI::App* cmd, SecurityFlags* security, const std::string& peer) {
  cmd->add_option("--token-file", security->token_file, "File holding the client token (else $TESSERA_CLIENT_TOKEN)")
      ->group("Security");
  cmd->add_option("--tls-ca", security->tls_ca,
                  "PEM CA certificate of the " + peer + ": connect with TLS (else $TESSERA_TLS_CA)")
      ->group("Security");
  cmd->add_option("--tls-cert", security->tls_cert, "PEM client certificate, for a " + peer + " that asks for one")
      ->group("Security");
  cmd->add_option("--tls-key", security->tls_key, "PEM private key of --tls-cert")->group("Security");
}

}  // namespace tessera::cli

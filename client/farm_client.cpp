// SPDX-License-Identifier: Apache-2.0
#include "farm_client.h"

#include <cstdlib>

#include "farm/channel.h"

namespace tessera::cli {

std::string resolve_coordinator(const std::string& flag) {
  if (!flag.empty()) return flag;
  const char* env = std::getenv("TESSERA_COORDINATOR");
  if (env && *env) return env;
  return farm::kDefaultCoordinator;
}

farm::ChannelSecurity resolve_security(const SecurityFlags& flags) {
  farm::ChannelSecurity s;
  s.token = farm::read_token(flags.token_file, "TESSERA_CLIENT_TOKEN");
  s.tls_ca = flags.tls_ca;
  if (s.tls_ca.empty()) {
    if (const char* env = std::getenv("TESSERA_TLS_CA")) s.tls_ca = env;
  }
  s.tls_cert = flags.tls_cert;
  s.tls_key = flags.tls_key;
  return s;
}

FarmClient::FarmClient(std::string address, const farm::ChannelSecurity& security, std::chrono::seconds timeout)
    : address_(std::move(address)), timeout_(timeout), tls_(!security.tls_ca.empty()) {
  channel_ = farm::make_coordinator_channel(address_, security);
  stub_ = tessera::v1::ClientService::NewStub(channel_);
}

bool FarmClient::wait_for_coordinator(std::chrono::milliseconds up_to) const {
  return farm::wait_for_coordinator(*channel_, up_to);
}

std::unique_ptr<grpc::ClientContext> FarmClient::context() const { return context(timeout_); }

std::unique_ptr<grpc::ClientContext> FarmClient::context(std::chrono::seconds deadline) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + deadline);
  return ctx;
}

std::string FarmClient::describe(const grpc::Status& s, const std::string& what) const {
  switch (s.error_code()) {
    case grpc::StatusCode::UNAVAILABLE:
      // A plaintext client at a TLS port: the server reads our HTTP/2 preface as a bad TLS
      // handshake and closes the socket.
      if (!tls_ && s.error_message().find("Socket closed") != std::string::npos) {
        return "the coordinator at " + address_ + " closed the connection (" + s.error_message() +
               "): if it speaks TLS, pass --tls-ca CA.pem (or set TESSERA_TLS_CA)";
      }
      return "cannot reach the coordinator at " + address_ + " (" + s.error_message() +
             "). Is it running? Start one with: tessera-server --listen " + address_ +
             " --data-dir DIR  (or point --coordinator / TESSERA_COORDINATOR at yours)";
    case grpc::StatusCode::UNAUTHENTICATED:
      return "the coordinator at " + address_ + " refused " + what + ": " + s.error_message() +
             " (give the client token with --token-file FILE or TESSERA_CLIENT_TOKEN)";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "the coordinator at " + address_ + " did not answer " + what + " in time";
    default:
      return what + ": " + s.error_message();
  }
}

}  // namespace tessera::cli

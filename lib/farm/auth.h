// SPDX-License-Identifier: Apache-2.0
// Shared-secret tokens for the two kinds of peers. Clients and workers send
// `authorization: Bearer <token>` metadata on every call (farm/channel.h adds it); each
// ClientService method checks the client token, each WorkerService method the worker token.
// A role with no token configured is open (and main() warns when it listens beyond loopback).
//
// Why a check at the top of every service method rather than one hook: in gRPC 1.51 a server
// interceptor cannot end a call with a status of its choosing (only cancel it: the peer would see
// CANCELLED, not UNAUTHENTICATED), and an AuthMetadataProcessor only runs on TLS credentials
// (tokens must also work on plaintext loopback) and would also guard health and reflection,
// which stay open for container health checks. One-line checks, each tested, are simpler.
#pragma once

#include <grpcpp/grpcpp.h>

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "farm/farm_error.h"

namespace CLI {
class App;
}

namespace tessera::farm {

enum class PeerRole { kClient, kWorker };

class Authenticator {
 public:
  Authenticator() = default;  // open: every call accepted
  // Empty tokens mean "open" for that role. Throws FarmError when both are set and
  // equal (the worker token must not grant client calls, nor the other way round), or when a
  // named client token (client_tokens.h: name -> token) equals the worker token.
  Authenticator(const std::string& client_token, const std::string& worker_token,
                const std::map<std::string, std::string>& named_client_tokens = {});

  bool open(PeerRole role) const;
  // OK, or UNAUTHENTICATED saying what was missing or wrong (never echoing the token). For a
  // named client token, `*name` is set to its name (left empty for the shared token).
  grpc::Status check(const grpc::ServerContextBase& ctx, PeerRole role, std::string* name = nullptr) const;
  // The same check on the value of an `authorization` header ("Bearer TOKEN"; nullopt when the
  // request had none): the HTTP monitor checks its requests with it.
  grpc::Status check_authorization(std::optional<std::string_view> value, PeerRole role,
                                   std::string* name = nullptr) const;

 private:
  using Digest = std::array<unsigned char, 32>;
  std::optional<Digest> client_, worker_;
  std::vector<std::pair<std::string, Digest>> named_;  // named client tokens
};

// The server's security flags: tokens (files, else TESSERA_CLIENT_TOKEN / TESSERA_WORKER_TOKEN)
// and TLS. With --tls-cert/--tls-key every connection is TLS; adding --tls-ca makes the server
// require and verify client certificates signed by that CA (mutual TLS) as well.
struct ServerSecurity {
  std::string client_token_file, worker_token_file, tls_cert, tls_key, tls_ca;
  std::string client_tokens;  // --client-tokens: named client tokens (client_tokens.h)

  void add_flags(CLI::App& app);
  // Both throw FarmError with a message naming the file or flag.
  Authenticator authenticator() const;
  std::shared_ptr<grpc::ServerCredentials> credentials() const;
  // One line on what is protected, and a warning when a non-loopback address is open.
  void log_posture(const std::string& listen, const Authenticator& auth) const;
};

// Refusals for streaming methods: a reactor that finishes at once with `status`.
template <class Base>
class Refused : public Base {
 public:
  explicit Refused(grpc::Status status) { this->Finish(std::move(status)); }
  void OnDone() override { delete this; }
};

}  // namespace tessera::farm

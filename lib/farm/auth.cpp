// SPDX-License-Identifier: Apache-2.0
#include "farm/auth.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "farm/channel.h"
#include "farm/client_tokens.h"
#include "farm/farm_error.h"

namespace tessera::farm {

namespace {

std::array<unsigned char, 32> digest(std::string_view s) {
  std::array<unsigned char, 32> d{};
  unsigned int len = 0;
  if (EVP_Digest(s.data(), s.size(), d.data(), &len, EVP_sha256(), nullptr) != 1 || len != d.size()) {
    throw FarmError("SHA-256 failed (OpenSSL)");
  }
  return d;
}

constexpr std::string_view kBearer = "Bearer ";

}  // namespace

Authenticator::Authenticator(const std::string& client_token, const std::string& worker_token,
                             const std::map<std::string, std::string>& named_client_tokens) {
  if (!client_token.empty() && client_token == worker_token) {
    throw FarmError("the client and worker tokens must differ (a worker must not be able to submit jobs)");
  }
  for (const auto& [name, token] : named_client_tokens) {
    if (token == worker_token) {
      throw FarmError("the token of client '" + name + "' is the worker token: they must differ");
    }
    named_.emplace_back(name, digest(token));
  }
  if (!client_token.empty()) client_ = digest(client_token);
  if (!worker_token.empty()) worker_ = digest(worker_token);
}

bool Authenticator::open(PeerRole role) const {
  return role == PeerRole::kClient ? !client_ && named_.empty() : !worker_;
}

grpc::Status Authenticator::check(const grpc::ServerContextBase& ctx, PeerRole role, std::string* name) const {
  if (open(role)) return grpc::Status::OK;
  const auto& md = ctx.client_metadata();
  const auto it = md.find("authorization");
  if (it == md.end()) return check_authorization(std::nullopt, role, name);
  return check_authorization(std::string_view(it->second.data(), it->second.size()), role, name);
}

grpc::Status Authenticator::check_authorization(std::optional<std::string_view> value, PeerRole role,
                                                std::string* name) const {
  if (open(role)) return grpc::Status::OK;
  const auto& want = role == PeerRole::kClient ? client_ : worker_;
  const char* who = role == PeerRole::kClient ? "client" : "worker";
  if (!value) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        std::string("this coordinator requires a ") + who + " token (authorization: Bearer metadata)");
  }
  // Compare SHA-256 digests with CRYPTO_memcmp: constant time, and the length of the real token
  // does not leak through the comparison either.
  if (value->substr(0, kBearer.size()) != kBearer) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, std::string("invalid ") + who + " token");
  }
  const Digest got = digest(value->substr(kBearer.size()));
  if (want && CRYPTO_memcmp(got.data(), want->data(), want->size()) == 0) return grpc::Status::OK;
  if (role == PeerRole::kClient) {
    // Every named token is compared (constant time each): which one matched does not show in
    // the time taken.
    const std::string* match = nullptr;
    for (const auto& [n, d] : named_) {
      if (CRYPTO_memcmp(got.data(), d.data(), d.size()) == 0) match = &n;
    }
    if (match) {
      if (name) *name = *match;
      return grpc::Status::OK;
    }
  }
  return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, std::string("invalid ") + who + " token");
}

void ServerSecurity::add_flags(CLI::App& app) {
  app.add_option("--client-token-file", client_token_file,
                 "File holding the token clients must send (else env TESSERA_CLIENT_TOKEN; none: open)")
      ->group("Security");
  app.add_option("--client-tokens", client_tokens,
                 "Named client tokens: a file of name:token lines, or a directory of files NAME holding a token. "
                 "Each name is a client identity (token:NAME) that owns the jobs it submits")
      ->group("Security");
  app.add_option("--worker-token-file", worker_token_file,
                 "File holding the token workers must send (else env TESSERA_WORKER_TOKEN; none: open)")
      ->group("Security");
  app.add_option("--tls-cert", tls_cert, "PEM certificate of this server: TLS on every connection")->group("Security");
  app.add_option("--tls-key", tls_key, "PEM private key of --tls-cert")->group("Security");
  app.add_option("--tls-ca", tls_ca, "PEM CA: also require client certificates signed by it (mutual TLS)")
      ->group("Security");
}

Authenticator ServerSecurity::authenticator() const {
  return Authenticator(farm::read_token(client_token_file, "TESSERA_CLIENT_TOKEN"),
                       farm::read_token(worker_token_file, "TESSERA_WORKER_TOKEN"),
                       client_tokens.empty() ? std::map<std::string, std::string>{} : read_client_tokens(client_tokens));
}

std::shared_ptr<grpc::ServerCredentials> ServerSecurity::credentials() const {
  if (tls_cert.empty() != tls_key.empty()) throw FarmError("--tls-cert and --tls-key go together");
  if (tls_cert.empty()) {
    if (!tls_ca.empty()) throw FarmError("--tls-ca needs --tls-cert and --tls-key (this server's own)");
    return grpc::InsecureServerCredentials();
  }
  grpc::SslServerCredentialsOptions ssl(tls_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                                       : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  if (!tls_ca.empty()) ssl.pem_root_certs = farm::read_pem(tls_ca, "client CA certificate (--tls-ca)");
  ssl.pem_key_cert_pairs.push_back(
      {farm::read_pem(tls_key, "private key (--tls-key)"), farm::read_pem(tls_cert, "certificate (--tls-cert)")});
  return grpc::SslServerCredentials(ssl);
}

void ServerSecurity::log_posture(const std::string& listen, const Authenticator& auth) const {
  const bool tls = !tls_cert.empty();
  spdlog::info("security: {}, client calls {}, worker calls {}",
               tls ? (tls_ca.empty() ? "TLS" : "mutual TLS (client certificates required)") : "plaintext",
               auth.open(PeerRole::kClient) ? "open" : "need the client token",
               auth.open(PeerRole::kWorker) ? "open" : "need the worker token");
  const std::string host = listen.substr(0, listen.rfind(':'));
  const bool loopback = host == "localhost" || host.rfind("127.", 0) == 0 || host == "[::1]" || host == "::1";
  if (!loopback && (auth.open(PeerRole::kClient) || auth.open(PeerRole::kWorker))) {
    spdlog::warn("listening on {} without {}: anyone who can reach it can {}. Give --client-token-file and "
                 "--worker-token-file (and --tls-cert/--tls-key).",
                 listen, auth.open(PeerRole::kClient) ? "a client token" : "a worker token",
                 auth.open(PeerRole::kClient) ? "submit and cancel jobs" : "pose as a worker");
  }
  if (!loopback && !tls && !(auth.open(PeerRole::kClient) && auth.open(PeerRole::kWorker))) {
    spdlog::warn("tokens travel in plaintext on {}: use --tls-cert/--tls-key beyond a trusted network", listen);
  }
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
#include "farm/channel.h"

#include <grpcpp/support/client_interceptor.h>

#include <cstdlib>

#include "farm/farm_error.h"
#include "farm/text_file.h"

namespace tessera::farm {

namespace {

// Adds the bearer token to the initial metadata of every call on the channel.
class BearerInterceptor : public grpc::experimental::Interceptor {
 public:
  explicit BearerInterceptor(const std::string& value) : value_(value) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      methods->GetSendInitialMetadata()->insert({"authorization", value_});
    }
    methods->Proceed();
  }

 private:
  const std::string& value_;
};

class BearerFactory : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit BearerFactory(std::string token) : value_("Bearer " + std::move(token)) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(grpc::experimental::ClientRpcInfo*) override {
    return new BearerInterceptor(value_);
  }

 private:
  std::string value_;  // outlives the channel's calls: the channel owns the factory
};

}  // namespace

std::string read_token(const std::string& file, const char* env) {
  if (!file.empty()) {
    std::string t;
    try {
      t = trim_blanks(read_text_file(file));
    } catch (const FarmError&) {
      throw FarmError("cannot read token file " + file);
    }
    if (t.empty()) throw FarmError("token file " + file + " is empty");
    return t;
  }
  const char* v = env ? std::getenv(env) : nullptr;
  return v ? trim_blanks(v) : std::string();
}

std::string read_pem(const std::string& file, const std::string& what) {
  std::string pem;
  try {
    pem = read_text_file(file);
  } catch (const FarmError&) {
    pem.clear();  // unreadable: the same answer as a file that is not PEM
  }
  if (pem.find("-----BEGIN") == std::string::npos) {
    throw FarmError("cannot read " + what + " " + file + " (a PEM file)");
  }
  return pem;
}

grpc::ChannelArguments coordinator_channel_args() {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 10000);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  args.SetInt(GRPC_ARG_MAX_RECEIVE_MESSAGE_LENGTH, 64 << 20);
  return args;
}

std::shared_ptr<grpc::Channel> make_coordinator_channel(const std::string& address, const ChannelSecurity& security) {
  grpc::ChannelArguments args = coordinator_channel_args();
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (!security.tls_ca.empty()) {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = read_pem(security.tls_ca, "CA certificate (--tls-ca)");
    if (security.tls_cert.empty() != security.tls_key.empty()) {
      throw FarmError("--tls-cert and --tls-key go together");
    }
    if (!security.tls_cert.empty()) {
      ssl.pem_cert_chain = read_pem(security.tls_cert, "certificate (--tls-cert)");
      ssl.pem_private_key = read_pem(security.tls_key, "private key (--tls-key)");
    }
    creds = grpc::SslCredentials(ssl);
  } else {
    if (!security.tls_cert.empty() || !security.tls_key.empty()) {
      throw FarmError("--tls-cert/--tls-key need --tls-ca (the CA that signed the coordinator's certificate)");
    }
    creds = grpc::InsecureChannelCredentials();
  }
  if (security.token.empty()) return grpc::CreateCustomChannel(address, creds, args);
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> interceptors;
  interceptors.push_back(std::make_unique<BearerFactory>(security.token));
  return grpc::experimental::CreateCustomChannelWithInterceptors(address, creds, args, std::move(interceptors));
}

bool wait_for_coordinator(grpc::Channel& channel, std::chrono::milliseconds up_to, const std::function<bool()>& stop) {
  const auto end = std::chrono::system_clock::now() + up_to;
  while (!(stop && stop())) {
    const auto now = std::chrono::system_clock::now();
    if (now >= end) return false;
    // WaitForConnected asks the channel to connect (GetState(true)) and returns once it is.
    if (channel.WaitForConnected(std::min(end, now + std::chrono::milliseconds(100)))) return true;
  }
  return false;
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
// The client's connection to a coordinator: address resolution, channel settings, deadlines,
// and error messages that say what is wrong and what to do about it.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "farm/channel.h"
#include "tessera/v1/client_service.grpc.pb.h"

namespace tessera::cli {

// --coordinator if given, else $TESSERA_COORDINATOR, else farm::kDefaultCoordinator.
std::string resolve_coordinator(const std::string& flag);

// --token-file, --tls-ca, --tls-cert, --tls-key of the farm commands.
struct SecurityFlags {
  std::string token_file, tls_ca, tls_cert, tls_key;
};
// The flags, else $TESSERA_CLIENT_TOKEN and $TESSERA_TLS_CA. Throws std::runtime_error for an
// unreadable token file.
farm::ChannelSecurity resolve_security(const SecurityFlags& flags);

class FarmClient {
 public:
  explicit FarmClient(std::string address, const farm::ChannelSecurity& security = {},
                      std::chrono::seconds timeout = std::chrono::seconds(15));

  tessera::v1::ClientService::Stub& stub() { return *stub_; }
  const std::string& address() const { return address_; }
  // Waits up to `up_to` for the coordinator to be reachable; true as soon as it is.
  bool wait_for_coordinator(std::chrono::milliseconds up_to) const;
  // A context with the unary-call deadline.
  std::unique_ptr<grpc::ClientContext> context() const;
  // A context with a custom deadline.
  static std::unique_ptr<grpc::ClientContext> context(std::chrono::seconds deadline);
  // "cannot reach the coordinator at ... start one with ..." and friends.
  std::string describe(const grpc::Status& s, const std::string& what) const;

 private:
  std::string address_;
  std::chrono::seconds timeout_;
  bool tls_ = false;  // the channel uses TLS (--tls-ca)
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<tessera::v1::ClientService::Stub> stub_;
};

}  // namespace tessera::cli

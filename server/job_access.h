// SPDX-License-Identifier: Apache-2.0
// Who may watch, cancel or acknowledge a job: the identity that submitted it (its owner, stored
// with the job) or an administrator (`tessera-server --admin IDENTITY`). Anyone may still read
// a job's status.
//
// Identities (farm/client_identity.h): "cn:NAME" for a TLS client certificate,
// "token:NAME" for a named client token (client_tokens.h), else the peer's address
// ("ipv4:10.0.0.7"). Only the first two authenticate a person; an address does not (a shared
// token or an open farm says nothing about who is calling, and addresses change with NAT and
// containers), so jobs owned by an address stay open to every client, as they always were.
#pragma once

#include <grpcpp/grpcpp.h>

#include <set>
#include <string>

namespace tessera::server {

struct Caller {
  std::string identity;
  bool admin = false;
};

// True for identities that prove who the caller is ("cn:", "token:").
bool authenticated_identity(const std::string& identity);

// OK, or PERMISSION_DENIED naming the job, its owner and the caller. `action`: "watch",
// "cancel", "acknowledge frames of".
grpc::Status check_job_access(const std::string& job, const std::string& owner, const Caller& caller,
                              const char* action);

}  // namespace tessera::server

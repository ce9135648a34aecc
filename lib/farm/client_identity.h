// SPDX-License-Identifier: Apache-2.0
// Who a client is, for job ownership and quotas.
#pragma once

#include <grpcpp/grpcpp.h>

#include <string>

namespace tessera::farm {

// The identity a client's jobs are counted under and owned by (the coordinator's job access rules): "cn:CN" of a TLS
// client certificate, else "token:NAME" of a named client token (`token_name`, from
// Authenticator::check), else the peer's address without the port.
std::string client_identity(const grpc::ServerContextBase& ctx, const std::string& token_name = {});

}  // namespace tessera::farm

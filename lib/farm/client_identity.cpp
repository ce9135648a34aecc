// SPDX-License-Identifier: Apache-2.0
#include "farm/client_identity.h"

namespace tessera::farm {

std::string client_identity(const grpc::ServerContextBase& ctx, const std::string& token_name) {
  if (auto auth = ctx.auth_context()) {
    for (const auto& cn : auth->FindPropertyValues(GRPC_X509_CN_PROPERTY_NAME)) {
      return "cn:" + std::string(cn.data(), cn.size());
    }
  }
  if (!token_name.empty()) return "token:" + token_name;
  // "ipv4:127.0.0.1:54321" / "ipv6:[::1]:54321": the address without the port.
  const std::string peer = ctx.peer();
  const auto colon = peer.rfind(':');
  return colon == std::string::npos || colon < 5 ? peer : peer.substr(0, colon);
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
// What every Tessera gRPC server (the coordinator, the ray server) sets on its connections, in
// one place so that both treat long-lived streams and stray connections alike.
#pragma once

#include <grpcpp/server_builder.h>

namespace tessera::farm {

// Peers ping to keep long-lived streams honest (farm/channel.h: every 10 s, also without calls):
// their pings are accepted as often as every 5 s and never counted as strikes. A connection that
// has not completed its handshake (TLS and the HTTP/2 preface) within 10 s is closed (gRPC's
// default is 120 s), so idle or garbage connections cannot hold descriptors long.
void set_server_connection_args(grpc::ServerBuilder& builder);

}  // namespace tessera::farm

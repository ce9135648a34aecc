// The gRPC channel every Tessera peer (client or worker) opens to a coordinator.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace tessera::farm {

// Keepalive pings (10 s, 10 s timeout, also without calls) notice a coordinator that vanished
// without closing the connection on long-lived streams; 64 MiB messages carry tiles and
// bundles; gRPC's own reconnect backoff is capped at 2 s so a restarted coordinator is found
// quickly (callers add their own backoff on top).
std::shared_ptr<grpc::Channel> make_coordinator_channel(const std::string& address);

}  // namespace tessera::farm

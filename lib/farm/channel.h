// SPDX-License-Identifier: Apache-2.0
// The gRPC channel every Tessera peer (client or worker) opens to a coordinator.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "farm/farm_error.h"

namespace tessera::farm {

// The coordinator's address when none is given: where tessera-server listens by default, and
// where workers, ray servers and the CLI look for it.
inline constexpr const char* kDefaultCoordinator = "127.0.0.1:7878";

// How a peer proves who it is and checks the coordinator. All empty: plaintext, no token (a
// coordinator without tokens, on a trusted network or loopback).
struct ChannelSecurity {
  std::string tls_ca;    // PEM file of the CA that signed the coordinator's certificate: TLS on
  std::string tls_cert;  // PEM certificate and key of this peer, for a coordinator that asks for
  std::string tls_key;   //   client certificates (--tls-ca on the server); optional
  std::string token;     // shared secret, sent as "authorization: Bearer <token>" on every call
};

// Keepalive pings (10 s, 10 s timeout, also without calls) notice a coordinator that vanished
// without closing the connection on long-lived streams; 64 MiB messages carry tiles and
// bundles; gRPC's own reconnect backoff starts at 200 ms and is capped at 1 s so a restarted
// coordinator is found within about a second (callers wait with wait_for_coordinator, not a
// blind sleep). The token is added by a client interceptor,
// the one place every call of the channel passes, on plaintext and TLS channels alike (gRPC's
// call credentials refuse to travel without TLS). Throws FarmError for unreadable
// certificate files.
// The channel arguments every connection to a coordinator uses: keepalive (a dead coordinator
// or NAT drop is noticed in seconds) and the farm's message size limit.
grpc::ChannelArguments coordinator_channel_args();

std::shared_ptr<grpc::Channel> make_coordinator_channel(const std::string& address,
                                                        const ChannelSecurity& security = {});

// Waits up to `up_to` for the channel to be connected, returning true as soon as it is (false
// on timeout, or when `stop` says so; it is polled every 100 ms). A peer that lost its
// coordinator waits with this instead of sleeping its backoff: gRPC keeps retrying the
// connection by itself (at most 1 s apart), so a coordinator that is listening again is used at
// once, however long the peer's own backoff has grown (a worker that slept out a long backoff
// once stayed away for seconds after its coordinator came back).
bool wait_for_coordinator(grpc::Channel& channel, std::chrono::milliseconds up_to,
                          const std::function<bool()>& stop = {});

// A token: the contents of `file` if given (surrounding whitespace dropped), else the environment
// variable `env` (kept out of the command line, so it does not show in `ps`), else empty.
// Throws FarmError naming an unreadable or empty file.
std::string read_token(const std::string& file, const char* env);

// The whole contents of a PEM file; throws FarmError naming `what` and the file.
std::string read_pem(const std::string& file, const std::string& what);

}  // namespace tessera::farm

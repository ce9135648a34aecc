// SPDX-License-Identifier: Apache-2.0
// The tessera-rays servers that announced themselves to this coordinator (docs/rays.md, "Where it
// is served"): who they are, where clients reach them, when each was last heard from.
//
// In memory only, on purpose: this is liveness, not state. A server announces itself every period
// (5 s by default), so after a coordinator restart the list is whole again within one period;
// persisting it would only bring back servers that may have died meanwhile.
//
// A server is listed until 3 periods pass without an announcement: one late or lost announcement
// (a loaded machine, a reconnect, a coordinator restart that swallowed a call) must not hide a
// healthy server from clients, and a dead one is gone within 3 periods (15 s by default), after
// which clients stop picking it. Clients fall back to the next server anyway (`tessera rays`), so
// a short stale window costs a failed connect, not a failed query.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "scheduler.h"
#include "tessera/v1/client_service.pb.h"
#include "tessera/v1/worker_service.pb.h"

namespace tessera::server {

struct RayServerOptions {
  // The period a server asks for is kept within these bounds: a too-short one would turn
  // announcements into load on the coordinator's threads, a too-long one leaves dead servers
  // listed for a long time.
  std::chrono::milliseconds min_period{100};
  std::chrono::milliseconds max_period{std::chrono::minutes(5)};
  int expiry_periods = 3;  // see the comment at the top
  // Servers listed at once: announcements come with the worker token, so this only bounds what
  // a misconfigured fleet (a new id per announcement) can make the coordinator hold.
  size_t max_servers = 1024;
};

class RayServers {
 public:
  explicit RayServers(RayServerOptions options = {}, std::function<TimePoint()> now = [] { return Clock::now(); });

  // Records an announcement from `peer`; the ack says when to announce again and when the server
  // expires. INVALID_ARGUMENT for a missing id or an address that is not HOST:PORT,
  // RESOURCE_EXHAUSTED when max_servers are listed and this is a new one. A new server id at an
  // address already listed replaces the old entry (the server restarted on the same port). A
  // `leaving` announcement removes the server at once (it is shutting down).
  grpc::Status announce(const tessera::v1::RayServerAnnouncement& a, const std::string& peer,
                        tessera::v1::RayServerAnnouncementAck* ack);
  // The servers not expired, in the order they first announced.
  void list(tessera::v1::ListRayServersResponse* out);
  size_t live();

 private:
  struct Entry {
    tessera::v1::RayServerDescription server;
    std::string peer;
    TimePoint first, last;
    std::chrono::milliseconds expiry{0};
  };
  void expire_locked(TimePoint now);

  RayServerOptions options_;
  std::function<TimePoint()> now_;
  std::mutex mu_;
  std::vector<Entry> entries_;  // in order of first announcement; a farm has a handful
};

}  // namespace tessera::server

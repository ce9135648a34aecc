// SPDX-License-Identifier: Apache-2.0
#include "ray_servers.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace tessera::server {

namespace v1 = tessera::v1;
using grpc::Status;
using grpc::StatusCode;

namespace {

// "HOST:PORT" with a port in 1-65535 ("[v6]:PORT" too): the address is handed to clients as is,
// so it must be one they can dial.
bool is_host_port(const std::string& a) {
  const size_t colon = a.rfind(':');
  if (a.size() > 255 || colon == std::string::npos || colon == 0 || colon + 1 == a.size()) return false;
  if (std::any_of(a.begin(), a.end(), [](unsigned char c) { return c <= ' ' || c == '/' || c >= 0x7f; })) return false;
  const std::string port = a.substr(colon + 1);
  if (port.size() > 5 || !std::all_of(port.begin(), port.end(), [](unsigned char c) { return std::isdigit(c); })) {
    return false;
  }
  const int p = std::stoi(port);
  return p >= 1 && p <= 65535;
}

double seconds(std::chrono::steady_clock::duration d) { return std::chrono::duration<double>(d).count(); }

}  // namespace

RayServers::RayServers(RayServerOptions options, std::function<TimePoint()> now)
    : options_(options), now_(std::move(now)) {}

Status RayServers::announce(const v1::RayServerAnnouncement& a, const std::string& peer,
                            v1::RayServerAnnouncementAck* ack) {
  const v1::RayServerDescription& s = a.server();
  if (s.server_id().empty() || s.server_id().size() > 128) {
    return Status(StatusCode::INVALID_ARGUMENT, "server.server_id: must be 1-128 characters");
  }
  if (!is_host_port(s.address())) {
    return Status(StatusCode::INVALID_ARGUMENT, "server.address: '" + s.address().substr(0, 64) +
                                                    "' is not HOST:PORT (tessera-rays --advertise)");
  }
  const auto period = std::clamp(std::chrono::milliseconds(a.period_ms()), options_.min_period, options_.max_period);
  const auto expiry = period * options_.expiry_periods;
  const TimePoint now = now_();
  std::lock_guard lock(mu_);
  expire_locked(now);
  auto it = std::find_if(entries_.begin(), entries_.end(),
                         [&](const Entry& e) { return e.server.server_id() == s.server_id(); });
  ack->set_period_ms(int32_t(period.count()));
  ack->set_expiry_ms(int32_t(expiry.count()));
  if (a.leaving()) {
    if (it != entries_.end()) {
      spdlog::info("ray server {} at {} is shutting down, no longer listed", s.server_id(), it->server.address());
      entries_.erase(it);
    }
    return Status::OK;
  }
  if (it == entries_.end()) {
    // The same address under a new id: that server restarted on its port; the old entry is stale.
    std::erase_if(entries_, [&](const Entry& e) {
      if (e.server.address() != s.address()) return false;
      spdlog::info("ray server {} at {} replaced by {} at the same address", e.server.server_id(), e.server.address(),
                   s.server_id());
      return true;
    });
    if (entries_.size() >= options_.max_servers) {
      return Status(StatusCode::RESOURCE_EXHAUSTED, "this coordinator lists at most " +
                                                        std::to_string(options_.max_servers) + " ray servers");
    }
    entries_.push_back(Entry{s, peer, now, now, expiry});
    spdlog::info("ray server {} at {} announced ({} threads, Embree {}, {}; from {}, listed until {} ms of silence)",
                 s.server_id(), s.address(), s.threads(), s.embree_isa(), s.tls() ? "TLS" : "plaintext", peer,
                 expiry.count());
  } else {
    if (it->server.address() != s.address()) {
      spdlog::info("ray server {} now at {} (was {})", s.server_id(), s.address(), it->server.address());
    }
    it->server = s;
    it->peer = peer;
    it->last = now;
    it->expiry = expiry;
  }
  return Status::OK;
}

void RayServers::list(v1::ListRayServersResponse* out) {
  const TimePoint now = now_();
  std::lock_guard lock(mu_);
  expire_locked(now);
  for (const Entry& e : entries_) {
    v1::RayServerInfo* info = out->add_servers();
    *info->mutable_server() = e.server;
    info->set_peer(e.peer);
    info->set_up_seconds(seconds(now - e.first));
    info->set_since_announcement_seconds(seconds(now - e.last));
    info->set_expiry_ms(int32_t(e.expiry.count()));
  }
}

size_t RayServers::live() {
  const TimePoint now = now_();
  std::lock_guard lock(mu_);
  expire_locked(now);
  return entries_.size();
}

void RayServers::expire_locked(TimePoint now) {
  std::erase_if(entries_, [&](const Entry& e) {
    if (now - e.last <= e.expiry) return false;
    spdlog::warn("ray server {} at {}: no announcement for {:.1f} s (expiry {} ms), no longer listed",
                 e.server.server_id(), e.server.address(), seconds(now - e.last), e.expiry.count());
    return true;
  });
}

}  // namespace tessera::server

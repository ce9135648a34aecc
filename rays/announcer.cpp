// SPDX-License-Identifier: Apache-2.0
#include "announcer.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <random>
#include <stdexcept>

namespace tessera::rayserver {

namespace v1 = tessera::v1;
using namespace std::chrono_literals;

Announcer::Announcer(v1::WorkerService::Stub& stub, std::string coordinator, std::chrono::milliseconds period,
                     std::function<v1::RayServerDescription()> describe)
    : stub_(stub), coordinator_(std::move(coordinator)), period_(period), describe_(std::move(describe)) {
  thread_ = std::thread([this] { loop(); });
}

Announcer::~Announcer() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
  if (!listed_) return;  // nothing to take back
  std::chrono::milliseconds deadline = 1s;
  int expiry_ms = 0;
  if (const std::string problem = announce_once(&deadline, &expiry_ms, true); !problem.empty()) {
    spdlog::warn("{}: the coordinator lists this server until it expires", problem);
  }
}

std::string Announcer::announce_once(std::chrono::milliseconds* period, int* expiry_ms, bool leaving) {
  v1::RayServerAnnouncement a;
  *a.mutable_server() = describe_();
  a.set_period_ms(int32_t(period_.count()));
  a.set_leaving(leaving);
  v1::RayServerAnnouncementAck ack;
  grpc::ClientContext ctx;
  // A call that outlives a period would delay the next announcement past the coordinator's patience.
  ctx.set_deadline(std::chrono::system_clock::now() + std::clamp<std::chrono::milliseconds>(*period, 1s, 10s));
  const grpc::Status s = stub_.AnnounceRayServer(&ctx, a, &ack);
  if (s.ok()) {
    if (ack.period_ms() > 0) *period = std::chrono::milliseconds(ack.period_ms());
    *expiry_ms = ack.expiry_ms();
    return "";
  }
  const std::string why = " (" + std::string(s.error_message()) + ")";
  switch (s.error_code()) {
    case grpc::StatusCode::UNAUTHENTICATED:
      return "the coordinator at " + coordinator_ + " refused the announcement: UNAUTHENTICATED" + why +
             ": it needs the coordinator's worker token (--worker-token-file, else $TESSERA_WORKER_TOKEN)";
    case grpc::StatusCode::UNIMPLEMENTED:
      return "the coordinator at " + coordinator_ +
             " does not list ray servers (a tessera-server older than AnnounceRayServer)" + why +
             "; run tessera-rays with --no-announce";
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "cannot reach the coordinator at " + coordinator_ + " to announce this ray server" + why;
    default:
      return "the coordinator at " + coordinator_ + " refused the announcement: " + std::to_string(s.error_code()) +
             why;
  }
}

void Announcer::loop() {
  std::chrono::milliseconds period = period_;
  // Retries after a failure start fast (a coordinator restarting is back in about a second) and
  // double up to the period, so a long outage costs one call per period.
  std::chrono::milliseconds backoff = 250ms;
  std::string problem = "not announced yet";
  std::unique_lock lock(mu_);
  while (!stopping_) {
    lock.unlock();
    int expiry_ms = 0;
    const std::string now = announce_once(&period, &expiry_ms);
    std::chrono::milliseconds wait = period;
    if (now.empty()) {
      if (!problem.empty()) {
        spdlog::info("announced to the coordinator at {} (every {} ms; listed until {} ms without one)", coordinator_,
                     period.count(), expiry_ms);
      }
      backoff = 250ms;
    } else {
      if (now != problem) {  // once per problem, not once per retry
        spdlog::warn("{}; retrying, and serving clients that name this server (--server) meanwhile", now);
      }
      wait = std::min(backoff, period);
      backoff = std::min(backoff * 2, period);
    }
    problem = now;
    lock.lock();
    listed_ = now.empty();
    cv_.wait_for(lock, wait, [this] { return stopping_; });
  }
}

std::string advertised_address(const std::string& listen, const std::string& advertise, int port) {
  const std::string bound = ":" + std::to_string(port);
  if (!advertise.empty()) {
    const size_t colon = advertise.rfind(':'), bracket = advertise.rfind(']');
    const bool v6_bare = bracket == std::string::npos && advertise.find(':') != colon;
    if (v6_bare) return "[" + advertise + "]" + bound;
    const bool has_port = colon != std::string::npos && (bracket == std::string::npos || colon > bracket);
    return has_port ? advertise : advertise + bound;
  }
  const std::string host = listen.substr(0, listen.rfind(':'));
  if (host.empty() || host == "0.0.0.0" || host == "[::]" || host == "::" || host == "[::0]" || host == "*") {
    throw std::invalid_argument("--listen " + listen +
                                " serves every interface, so there is no one address to announce to the coordinator: "
                                "pass --advertise HOST[:PORT] (the address clients should dial), or --no-announce");
  }
  return host + bound;
}

std::string new_server_id() {
  std::random_device rd;
  const uint64_t v = (uint64_t(rd()) << 32) | rd();
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)v);
  return buf;
}

}  // namespace tessera::rayserver

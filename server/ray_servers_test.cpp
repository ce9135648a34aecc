// SPDX-License-Identifier: Apache-2.0
// The ray server registry with a clock the test moves: listing, expiry after 3 periods of
// silence (not before), renewal by a later announcement, the period bounds, a restart on the same
// address, a server leaving, and refused announcements.
#include "ray_servers.h"

#include <gtest/gtest.h>

namespace tessera::server {
namespace {

namespace v1 = tessera::v1;
using namespace std::chrono_literals;

struct Registry {
  explicit Registry(RayServerOptions options = {}) : servers(options, [this] { return t; }) {}
  TimePoint t{};
  RayServers servers;

  grpc::Status announce(const std::string& id, const std::string& address, int period_ms = 1000,
                        v1::RayServerAnnouncementAck* ack_out = nullptr) {
    v1::RayServerAnnouncement a;
    a.mutable_server()->set_server_id(id);
    a.mutable_server()->set_address(address);
    a.mutable_server()->set_embree_isa("avx2");
    a.set_period_ms(period_ms);
    v1::RayServerAnnouncementAck ack;
    grpc::Status s = servers.announce(a, "ipv4:127.0.0.1:5555", &ack);
    if (ack_out) *ack_out = ack;
    return s;
  }
  std::vector<std::string> addresses() {
    v1::ListRayServersResponse r;
    servers.list(&r);
    std::vector<std::string> out;
    for (const auto& s : r.servers()) out.push_back(s.server().address());
    return out;
  }
};

TEST(RayServers, ListedUntilThreePeriodsOfSilence) {
  Registry r;
  v1::RayServerAnnouncementAck ack;
  ASSERT_TRUE(r.announce("a", "10.0.0.1:7879", 1000, &ack).ok());
  EXPECT_EQ(ack.period_ms(), 1000);
  EXPECT_EQ(ack.expiry_ms(), 3000);
  r.t += 500ms;
  ASSERT_TRUE(r.announce("b", "10.0.0.2:7879").ok());
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"10.0.0.1:7879", "10.0.0.2:7879"}));
  v1::ListRayServersResponse list;
  r.servers.list(&list);
  EXPECT_EQ(list.servers(0).server().embree_isa(), "avx2");
  EXPECT_EQ(list.servers(0).peer(), "ipv4:127.0.0.1:5555");
  EXPECT_DOUBLE_EQ(list.servers(0).since_announcement_seconds(), 0.5);
  EXPECT_EQ(list.servers(0).expiry_ms(), 3000);
  r.t += 2500ms;  // a: exactly 3 s of silence, still listed
  EXPECT_EQ(r.servers.live(), 2u);
  r.t += 1ms;     // a: past it
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"10.0.0.2:7879"}));
  ASSERT_TRUE(r.announce("b", "10.0.0.2:7879").ok());  // b renews
  r.t += 2900ms;
  EXPECT_EQ(r.servers.live(), 1u);
  r.t += 101ms;
  EXPECT_EQ(r.servers.live(), 0u);
  // An expired server that announces again is listed again (a network partition healed).
  ASSERT_TRUE(r.announce("a", "10.0.0.1:7879").ok());
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"10.0.0.1:7879"}));
}

TEST(RayServers, PeriodIsKeptWithinBounds) {
  Registry r;
  v1::RayServerAnnouncementAck ack;
  ASSERT_TRUE(r.announce("a", "h:1", 1, &ack).ok());
  EXPECT_EQ(ack.period_ms(), 100);
  EXPECT_EQ(ack.expiry_ms(), 300);
  ASSERT_TRUE(r.announce("a", "h:1", 0, &ack).ok());  // unset: the minimum, not "never expires"
  EXPECT_EQ(ack.expiry_ms(), 300);
  ASSERT_TRUE(r.announce("a", "h:1", 3600 * 1000, &ack).ok());
  EXPECT_EQ(ack.period_ms(), 300 * 1000);
}

TEST(RayServers, NewIdAtTheSameAddressReplacesTheOldEntry) {
  Registry r;
  ASSERT_TRUE(r.announce("old", "h:7879").ok());
  ASSERT_TRUE(r.announce("other", "h:7880").ok());
  ASSERT_TRUE(r.announce("new", "h:7879").ok());
  v1::ListRayServersResponse list;
  r.servers.list(&list);
  ASSERT_EQ(list.servers_size(), 2);
  EXPECT_EQ(list.servers(0).server().server_id(), "other");
  EXPECT_EQ(list.servers(1).server().server_id(), "new");
  // The same id at a new address moves (a server re-advertised).
  ASSERT_TRUE(r.announce("new", "h:7881").ok());
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"h:7880", "h:7881"}));
}

TEST(RayServers, LeavingServerIsDroppedAtOnce) {
  Registry r;
  ASSERT_TRUE(r.announce("a", "h:1").ok());
  ASSERT_TRUE(r.announce("b", "h:2").ok());
  v1::RayServerAnnouncement bye;
  bye.mutable_server()->set_server_id("a");
  bye.mutable_server()->set_address("h:1");
  bye.set_leaving(true);
  v1::RayServerAnnouncementAck ack;
  ASSERT_TRUE(r.servers.announce(bye, "p", &ack).ok());
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"h:2"}));
  ASSERT_TRUE(r.servers.announce(bye, "p", &ack).ok());  // twice, or unknown: nothing to do
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"h:2"}));
}

TEST(RayServers, RefusesWhatClientsCouldNotUse) {
  Registry r;
  for (const char* bad : {"", "host", "host:", ":7879", "host:0", "host:70000", "host:12x", "a b:1", "http://h:1"}) {
    const grpc::Status s = r.announce("a", bad);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_NE(s.error_message().find("server.address"), std::string::npos) << s.error_message();
  }
  EXPECT_EQ(r.announce("", "h:1").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_TRUE(r.announce("a", "[::1]:7879").ok());
  EXPECT_EQ(r.addresses(), (std::vector<std::string>{"[::1]:7879"}));
}

TEST(RayServers, BoundedCount) {
  RayServerOptions o;
  o.max_servers = 2;
  Registry r(o);
  ASSERT_TRUE(r.announce("a", "h:1").ok());
  ASSERT_TRUE(r.announce("b", "h:2").ok());
  EXPECT_EQ(r.announce("c", "h:3").error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(r.announce("a", "h:1").ok());  // a known one still renews
  r.t += 3001ms;                              // both expire: room again
  EXPECT_TRUE(r.announce("c", "h:3").ok());
}

}  // namespace
}  // namespace tessera::server

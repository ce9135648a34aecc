// SPDX-License-Identifier: Apache-2.0
// Ray servers found through the coordinator (docs/rays.md "Where it is served"), with
// real processes: tessera-rays announces itself, `tessera rayservers` lists it, `tessera rays
// --coordinator` without --server uses it (answers byte-identical to the in-process run), a
// killed server expires and the client says so, a stopped one leaves at once, a restarted coordinator lists it again, a wrong
// worker token is refused, and a dead listed server is skipped for the next one.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "rays_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;

// Short periods keep the tests quick: listed until 3 periods of silence.
const std::vector<std::string> kFastAnnounce{"--announce-seconds", "0.2"};

// `tessera rayservers --json`: the servers the coordinator lists now.
json listed(Farm& farm, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args{"rayservers", "--json", "--coordinator", farm.address()};
  args.insert(args.end(), extra.begin(), extra.end());
  const CliResult r = farm.cli(args);
  if (r.code != 0) {
    ADD_FAILURE() << "tessera rayservers failed: " << r.output;
    return json::array();
  }
  return json::parse(r.output.substr(r.output.find('[')));
}

bool lists(Farm& farm, const std::string& address, const std::vector<std::string>& extra = {}) {
  for (const json& s : listed(farm, extra)) {
    if (s["address"] == address) return true;
  }
  return false;
}

// A farm's coordinator and one tessera-rays announcing itself every 0.2 s, once it is listed.
std::string start_listed_rays(Farm& farm, std::unique_ptr<Process>* rays) {
  farm.start_server();
  const std::string addr = start_rays(farm, rays, kFastAnnounce);
  EXPECT_TRUE(eventually([&] { return lists(farm, addr); })) << (*rays)->log() << farm.server_logs();
  return addr;
}

std::string sphere_scene() { return source("tests/rays/sphere_scene.json").string(); }

fs::path one_ray(Farm& farm) {
  const fs::path in = farm.dir() / "one.csv";
  std::ofstream(in) << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n";
  return in;
}

TEST(RaysDiscovery, AnnouncedServerIsListedAndAnswersLikeInProcess) {
  Farm farm;
  std::unique_ptr<Process> rays;
  const std::string addr = start_listed_rays(farm, &rays);
  ASSERT_FALSE(::testing::Test::HasFailure());
  const json s = listed(farm)[0];
  std::smatch isa;
  const std::string log = rays->log();
  ASSERT_TRUE(std::regex_search(log, isa, std::regex("Embree (\\S+)"))) << log;
  EXPECT_EQ(s["embree_isa"], isa[1].str());
  EXPECT_EQ(s["threads"], 2);
  EXPECT_EQ(s["max_batch_rays"], 262144);
  EXPECT_EQ(s["tls"], false);
  EXPECT_EQ(s["version"], "tessera-rays 0.1.0");
  EXPECT_EQ(s["server_id"].get<std::string>().size(), 16u);
  // The table names it too.
  const CliResult table = farm.cli({"rayservers", "--coordinator", farm.address()});
  ASSERT_EQ(table.code, 0) << table.output;
  EXPECT_NE(table.output.find(addr), std::string::npos) << table.output;

  const fs::path in = farm.dir() / "rays.csv", local = farm.dir() / "local.csv", remote = farm.dir() / "remote.csv";
  write_bunny_rays(in, 3000);
  const std::string scene = source("scenes/bunny.json").string();
  CliResult r = farm.cli({"rays", scene, "--in", in.string(), "--out", local.string()});
  ASSERT_EQ(r.code, 0) << r.output;
  r = farm.cli({"rays", scene, "--in", in.string(), "--out", remote.string(), "--coordinator", farm.address(),
                "--batch", "1000"});
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  EXPECT_NE(r.output.find("3000 rays"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("via " + addr), std::string::npos) << r.output;
  EXPECT_EQ(read_text(local), read_text(remote));
  // Its counters reach the listing with its next announcements: 3 batches, 3000 rays.
  EXPECT_TRUE(eventually([&] {
    const json now = listed(farm);
    return !now.empty() && now[0]["rays"] == 3000 && now[0]["requests"] == 3;
  })) << listed(farm).dump();
}

TEST(RaysDiscovery, KilledServerExpiresAndTheClientSaysSo) {
  Farm farm;
  std::unique_ptr<Process> rays;
  const std::string addr = start_listed_rays(farm, &rays);
  ASSERT_FALSE(::testing::Test::HasFailure());
  rays->signal(SIGKILL);
  rays->wait(10s);
  ASSERT_TRUE(eventually([&] { return listed(farm).empty(); })) << listed(farm).dump();
  EXPECT_NE(farm.server_logs().find("at " + addr + ": no announcement for"), std::string::npos) << farm.server_logs();
  const CliResult r = farm.cli({"rays", sphere_scene(), "--in", one_ray(farm).string(), "--out",
                                (farm.dir() / "o.csv").string(), "--coordinator", farm.address()});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("no ray server is announced to the coordinator at " + farm.address() +
                          "; start tessera-rays --coordinator " + farm.address() + ", or pass --server"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(farm.dir() / "o.csv"));
}

// A bad command line is bad input: exit 2 naming the flag (farm/command_line.h).
TEST(RaysDiscovery, ABadFlagExitsTwoNamingIt) {
  Farm farm;
  Process p({(fs::path(TESSERA_BINARY_DIR) / "rays" / "tessera-rays").string(), "--announce-seconds", "never"},
            farm.dir() / "flags.log");
  EXPECT_EQ(p.wait(20s), 2) << p.log();
  EXPECT_NE(p.log().find("--announce-seconds"), std::string::npos) << p.log();
}

// Only the thread that waits for them takes SIGINT and SIGTERM (farm/stop_signals.h): gRPC's own
// threads, started when the credentials are made, block them too, so a stop is never a kill.
TEST(RaysDiscovery, OnlyTheWaitingThreadTakesStopSignals) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays);
  ASSERT_TRUE(eventually([&] { return lists(farm, addr); })) << rays->log();
  for (int sig : {SIGTERM, SIGINT}) {
    const std::vector<std::string> taking = threads_taking(rays->pid(), sig);
    std::string all;
    for (const auto& t : taking) all += "\n  " + t;
    ASSERT_EQ(taking.size(), 1u) << "signal " << sig << " can be taken by these threads:" << all;
    EXPECT_EQ(taking[0].rfind(std::to_string(rays->pid()) + " ", 0), 0u) << "not the main thread:" << all;
  }
}

// A server stopped with SIGTERM says it is leaving: gone from the list at once, not after 3 periods.
TEST(RaysDiscovery, StoppedServerLeavesTheListAtOnce) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays, {"--announce-seconds", "60"});  // would stay listed for 3 min
  ASSERT_TRUE(eventually([&] { return lists(farm, addr); })) << rays->log();
  rays->signal(SIGTERM);
  ASSERT_EQ(rays->wait(30s), 0) << rays->log();
  EXPECT_TRUE(listed(farm).empty()) << listed(farm).dump();
  EXPECT_NE(farm.server_logs().find("at " + addr + " is shutting down, no longer listed"), std::string::npos)
      << farm.server_logs();
}

// The registry is memory only: a restarted coordinator knows no ray server until they announce
// again, which they keep trying while it is down, serving clients all along.
TEST(RaysDiscovery, ListedAgainAfterTheCoordinatorRestarts) {
  Farm farm;
  std::unique_ptr<Process> rays;
  const std::string addr = start_listed_rays(farm, &rays);
  ASSERT_FALSE(::testing::Test::HasFailure());
  const std::string id = listed(farm)[0]["server_id"];
  farm.stop_server();
  ASSERT_TRUE(eventually([&] { return rays->log().find("cannot reach the coordinator") != std::string::npos; }))
      << rays->log();
  // Still serving with the coordinator down (its health service answers).
  const CliResult health = farm.cli({"health", "--coordinator", addr});
  EXPECT_EQ(health.code, 0) << health.output;
  farm.start_server(farm.server_extra());  // same port, same data dir
  ASSERT_TRUE(eventually([&] { return lists(farm, addr); })) << rays->log() << farm.server_logs();
  EXPECT_EQ(listed(farm)[0]["server_id"], id);  // the same server, not a new one
  EXPECT_TRUE(rays->running());
  const CliResult r = farm.cli({"rays", sphere_scene(), "--in", one_ray(farm).string(), "--out",
                                (farm.dir() / "o.csv").string(), "--coordinator", farm.address()});
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read_text(farm.dir() / "o.csv").substr(read_text(farm.dir() / "o.csv").find('\n') + 1, 4), "1,8,");
}

TEST(RaysDiscovery, WrongWorkerTokenIsRefusedAndNotListed) {
  Farm farm;
  std::ofstream(farm.dir() / "worker.token") << "worker-secret\n";
  std::ofstream(farm.dir() / "wrong.token") << "not-the-worker-secret\n";
  farm.start_server({"--worker-token-file", (farm.dir() / "worker.token").string()});
  std::unique_ptr<Process> wrong, right;
  const std::string wrong_addr =
      start_rays(farm, &wrong, {"--announce-seconds", "0.2", "--worker-token-file", (farm.dir() / "wrong.token").string()},
                 "wrong");
  const std::string right_addr =
      start_rays(farm, &right, {"--announce-seconds", "0.2", "--worker-token-file", (farm.dir() / "worker.token").string()},
                 "right");
  ASSERT_TRUE(eventually([&] { return wrong->log().find("UNAUTHENTICATED") != std::string::npos; })) << wrong->log();
  EXPECT_NE(wrong->log().find("refused the announcement: UNAUTHENTICATED"), std::string::npos) << wrong->log();
  EXPECT_NE(wrong->log().find("--worker-token-file"), std::string::npos) << wrong->log();
  // The right token is listed (so the listing works), the wrong one is not, however long it tries.
  ASSERT_TRUE(eventually([&] { return lists(farm, right_addr); })) << right->log();
  const json all = listed(farm);
  ASSERT_EQ(all.size(), 1u) << all.dump();
  EXPECT_EQ(all[0]["address"], right_addr);
  EXPECT_NE(farm.server_logs().find("ray server announcement from"), std::string::npos) << farm.server_logs();
  EXPECT_TRUE(wrong->running());  // refused, still serving clients that name it
  EXPECT_NE(wrong_addr, "");
}

// A listed server that died is skipped: the client tries the next one.
TEST(RaysDiscovery, DeadListedServerIsSkippedForTheNext) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> busy, dead;
  const std::string busy_addr = start_rays(farm, &busy, kFastAnnounce, "busy");
  // A long period: still listed well after it is killed.
  const std::string dead_addr = start_rays(farm, &dead, {"--announce-seconds", "30"}, "dead");
  const fs::path in = one_ray(farm);
  // `busy` has served rays, `dead` none: the client tries `dead` first (fewest rays served).
  CliResult r = farm.cli({"rays", sphere_scene(), "--in", in.string(), "--out", (farm.dir() / "o.csv").string(),
                          "--server", busy_addr, "--coordinator", farm.address()});
  ASSERT_EQ(r.code, 0) << r.output;
  ASSERT_TRUE(eventually([&] {
    const json all = listed(farm);
    return all.size() == 2 && std::any_of(all.begin(), all.end(), [&](const json& s) {
             return s["address"] == busy_addr && s["rays"] == 1;
           });
  })) << listed(farm).dump();
  dead->signal(SIGKILL);
  dead->wait(10s);
  r = farm.cli({"rays", sphere_scene(), "--in", in.string(), "--out", (farm.dir() / "o.csv").string(),
                "--coordinator", farm.address()});
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("ray server " + dead_addr + " (listed by the coordinator) does not answer"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("via " + busy_addr), std::string::npos) << r.output;
}

TEST(RaysDiscovery, WildcardListenNeedsAnAdvertisedAddress) {
  Farm farm;
  Process p({(fs::path(TESSERA_BINARY_DIR) / "rays" / "tessera-rays").string(), "--listen", "0.0.0.0:0",
             "--coordinator", "127.0.0.1:1", "--cache-dir", (farm.dir() / "c").string()},
            farm.dir() / "wildcard.log");
  EXPECT_EQ(p.wait(30s), 2) << p.log();
  EXPECT_NE(p.log().find("--listen 0.0.0.0:0 serves every interface"), std::string::npos) << p.log();
  EXPECT_NE(p.log().find("pass --advertise HOST[:PORT]"), std::string::npos) << p.log();
}

}  // namespace
}  // namespace tessera::farmtest

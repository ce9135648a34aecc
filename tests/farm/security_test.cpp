// SPDX-License-Identifier: Apache-2.0
// Security of the farm through the real processes: tokens (per role), TLS (right CA, plaintext,
// wrong CA, client certificates) and the coordinator's limits, each refused with the right code
// and a message naming the limit. The PKI is made per test run with openssl in a temp directory.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "farm_harness.h"
#include "test_pki.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 96x64, 4 spp, 3 frames, 4 objects

void write(const fs::path& p, const std::string& s) {
  std::ofstream(p) << s;
}

struct Tokens {
  fs::path client, worker, wrong;
};

Tokens make_tokens(const fs::path& dir) {
  Tokens t{dir / "client.token", dir / "worker.token", dir / "wrong.token"};
  write(t.client, "client-secret-6f1c2a\n");  // the trailing newline is not part of the token
  write(t.worker, "worker-secret-93be07\n");
  write(t.wrong, "client-secret-6f1c2b\n");
  return t;
}

// `tessera workers --json` with the given extra flags: the number of workers, or -1 on failure.
int count_workers(Farm& farm, const std::vector<std::string>& flags, std::string* output = nullptr) {
  std::vector<std::string> args{"workers", "--json", "--coordinator", farm.address()};
  args.insert(args.end(), flags.begin(), flags.end());
  CliResult r = farm.cli(args, 30s);
  if (output) *output = r.output;
  if (r.code != 0) return -1;
  return int(nlohmann::json::parse(r.output).size());
}

// Submits frame 0 of the test scene and checks the EXR is bit-identical to `tessera render`.
void expect_renders(Farm& farm, const std::vector<std::string>& flags) {
  const fs::path out = farm.dir() / "out" / "frame_####.exr";
  std::vector<std::string> args{"submit", kScene.string(), "--coordinator", farm.address(), "-o", out.string(),
                                "--frames", "0", "--tile", "32", "-q"};
  args.insert(args.end(), flags.begin(), flags.end());
  CliResult r = farm.cli(args);
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  EXPECT_EQ(compare_exr(farm.dir() / "out" / "frame_0000.exr", reference_frame(kScene, 0, {})), "");
}

bool has(const std::string& haystack, const std::string& needle) { return haystack.find(needle) != std::string::npos; }

TEST(FarmSecurity, TokensGuardEachRoleSeparately) {
  Farm farm;
  const Tokens t = make_tokens(farm.dir());
  farm.start_server({"--client-token-file", t.client.string(), "--worker-token-file", t.worker.string()});
  // Workers: one with the client token (refused), one with the right token.
  Process& impostor = farm.start_worker("impostor", 1, 0, {"--token-file", t.client.string()});
  farm.start_worker("w1", 1, 0, {"--token-file", t.worker.string()});

  std::string out;
  EXPECT_EQ(count_workers(farm, {}, &out), -1);
  EXPECT_TRUE(has(out, "requires a client token")) << out;
  EXPECT_EQ(count_workers(farm, {"--token-file", t.wrong.string()}, &out), -1);
  EXPECT_TRUE(has(out, "invalid client token")) << out;
  EXPECT_EQ(count_workers(farm, {"--token-file", t.worker.string()}, &out), -1) << "the worker token granted a client call";
  EXPECT_TRUE(has(out, "invalid client token")) << out;

  expect_renders(farm, {"--token-file", t.client.string()});
  // Only the worker with the worker token ever registered; the impostor was told why.
  EXPECT_EQ(count_workers(farm, {"--token-file", t.client.string()}), 1);
  EXPECT_TRUE(impostor.running());
  EXPECT_TRUE(has(impostor.log(), "invalid worker token")) << impostor.log();
  EXPECT_FALSE(has(farm.server().log(), "'impostor' joined")) << farm.server().log();

  // The same through an independent client: the worker token on a client call, a non-Bearer
  // scheme, and health checks staying open without a token.
  setenv("PROBE_WORKER_TOKEN", "worker-secret-93be07", 1);
  setenv("PROBE_CLIENT_TOKEN", "client-secret-6f1c2a", 1);
  Process py({"/usr/bin/python3", source("tests/farm/security_probe.py").string(), farm.address(),
              source("proto").string(), farm.dir().string(), "token-roles", "health"},
             farm.dir() / "probe.log");
  EXPECT_EQ(py.wait(60s), 0) << py.log();
  // Health answers for each service by name too, without a token.
  for (const char* service : {"tessera.v1.ClientService", "tessera.v1.WorkerService"}) {
    CliResult h = farm.cli({"health", "--coordinator", farm.address(), "--service", service});
    EXPECT_EQ(h.code, 0) << service << ": " << h.output;
  }
}

TEST(FarmSecurity, ServerRefusesEqualClientAndWorkerTokens) {
  Farm farm;
  const Tokens t = make_tokens(farm.dir());
  Process server({bin("tessera-server"), "--listen", "127.0.0.1:0", "--data-dir", (farm.dir() / "d").string(),
                  "--client-token-file", t.client.string(), "--worker-token-file", t.client.string()},
                 farm.dir() / "equal.log");
  EXPECT_EQ(server.wait(20s), 2);
  EXPECT_TRUE(has(server.log(), "must differ")) << server.log();
}

TEST(FarmSecurity, TlsWithTokensRendersAndRefusesPlaintextAndWrongCa) {
  Farm farm;
  const Pki pki = make_pki(farm.dir());
  const Tokens t = make_tokens(farm.dir());
  farm.start_server({"--tls-cert", pki.server_cert.string(), "--tls-key", pki.server_key.string(),
                     "--client-token-file", t.client.string(), "--worker-token-file", t.worker.string()});
  EXPECT_TRUE(has(farm.server().log(), "security: TLS")) << farm.server().log();
  farm.start_worker("w1", 1, 0, {"--tls-ca", pki.ca.string(), "--token-file", t.worker.string()});
  const std::vector<std::string> good{"--tls-ca", pki.ca.string(), "--token-file", t.client.string()};
  expect_renders(farm, good);

  std::string out;
  // Plaintext to a TLS port: the handshake never completes, nothing is answered; the client
  // says what to do instead of "is it running?".
  EXPECT_EQ(count_workers(farm, {"--token-file", t.client.string()}, &out), -1);
  EXPECT_TRUE(has(out, "if it speaks TLS, pass --tls-ca")) << out;
  // A client that trusts another CA refuses the server's certificate.
  EXPECT_EQ(count_workers(farm, {"--tls-ca", pki.other_ca.string(), "--token-file", t.client.string()}, &out), -1);
  EXPECT_TRUE(has(out, "cannot reach the coordinator")) << out;
  // TLS alone is not enough: the token is still required.
  EXPECT_EQ(count_workers(farm, {"--tls-ca", pki.ca.string()}, &out), -1);
  EXPECT_TRUE(has(out, "requires a client token")) << out;
  EXPECT_EQ(count_workers(farm, good), 1);
  // A worker trusting the wrong CA never joins.
  farm.start_worker("lost", 1, 0, {"--tls-ca", pki.other_ca.string(), "--token-file", t.worker.string()});
  std::this_thread::sleep_for(1500ms);
  EXPECT_EQ(count_workers(farm, good), 1);
}

TEST(FarmSecurity, MutualTlsRequiresAClientCertificate) {
  Farm farm;
  const Pki pki = make_pki(farm.dir());
  farm.start_server({"--tls-cert", pki.server_cert.string(), "--tls-key", pki.server_key.string(), "--tls-ca",
                     pki.ca.string()});
  farm.start_worker("w1", 1, 0,
                    {"--tls-ca", pki.ca.string(), "--tls-cert", pki.client_cert.string(), "--tls-key",
                     pki.client_key.string()});
  std::string out;
  EXPECT_EQ(count_workers(farm, {"--tls-ca", pki.ca.string()}, &out), -1) << "no client certificate, yet answered";
  const std::vector<std::string> good{"--tls-ca", pki.ca.string(), "--tls-cert", pki.client_cert.string(),
                                      "--tls-key", pki.client_key.string()};
  expect_renders(farm, good);
}

// Runs one security_probe.py check against the farm (it must pass), then returns the
// coordinator's peak resident memory in MiB.
double probe_peak_rss(Farm& farm, const std::string& check) {
  Process py({"/usr/bin/python3", source("tests/farm/security_probe.py").string(), farm.address(),
              source("proto").string(), farm.dir().string(), check},
             farm.dir() / ("probe-" + check + ".log"));
  EXPECT_EQ(py.wait(300s), 0) << py.log() << farm.server().log();
  const double peak = peak_rss_mib(farm.server().pid());
  std::printf("%s: coordinator peak RSS %.1f MiB\n%s", check.c_str(), peak, py.log().c_str());
  EXPECT_GT(peak, 0.0);
  return peak;
}

TEST(FarmSecurity, InstancedMeshOverThePrimitiveLimitIsRefusedBeforeItIsFlattened) {
  // 1,000 instances of a 20,000-triangle mesh took the coordinator to
  // 1.1 GB before --max-primitives 100000 refused it.
  Farm farm;
  farm.start_server({"--max-primitives", "100000"});
  const double peak = probe_peak_rss(farm, "instance-bomb");
  // The file is under 1 MB and the mesh 20,000 triangles: a few tens of MiB beyond the
  // coordinator's own ~30 MiB, not the ~1 GB that flattening 20 M triangles costs.
  if (kRssMeaningful) {
    EXPECT_LT(peak, 300.0);
  }
}

TEST(FarmSecurity, ConcurrentUploadsStreamToDiskAndAreBounded) {
  // Four concurrent 300 MB uploads with a wrong hash took the coordinator to
  // 1.7 GB. Here 4 x 100 MB: each goes to disk while hashed (one chunk in memory) and is refused
  // for its hash; a fifth concurrent upload is refused at once (--max-concurrent-uploads 4).
  Farm farm;
  farm.start_server({"--max-concurrent-uploads", "4"});
  const double peak = probe_peak_rss(farm, "upload-flood");
  if (kRssMeaningful) {
    EXPECT_LT(peak, 200.0);
  }
  // Nothing of them is left on disk.
  for (const auto& e : fs::directory_iterator(farm.data_dir() / "bundles")) {
    EXPECT_EQ(e.path().filename().string().rfind(".upload-", 0), std::string::npos) << e.path();
  }
}

// Uploads that stall end, and give their slot back: four streams that sent 1 MiB and then
// nothing held every slot for good (no timeout in 100 s), and every new scene was refused with
// "the number of bundle uploads in progress is 5, over this coordinator's limit 4". Now each is
// ended after --upload-idle-seconds without a chunk, its temporary file removed, and a normal
// submit of a new scene goes through while their clients still hold the streams open.
TEST(FarmSecurity, StalledUploadsTimeOutAndGiveTheirSlotsBack) {
  Farm farm;
  farm.start_server({"--max-concurrent-uploads", "4", "--upload-idle-seconds", "1"});
  farm.start_worker("w1");
  Process py({"/usr/bin/python3", source("tests/farm/security_probe.py").string(), farm.address(),
              source("proto").string(), farm.dir().string(), "upload-stall"},
             farm.dir() / "probe-upload-stall.log");
  for (int i = 0; i < 1200 && py.running() && !has(py.log(), "stalled uploads "); ++i) {
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_TRUE(has(py.log(), "stalled uploads ")) << py.log();
  // Whatever the stalled streams' fate, their clients hold them open while this submit runs.
  const CliResult r = farm.cli({"submit", source("tests/farm/chaos_orbit.json").string(), "--coordinator",
                                farm.address(), "--frames", "0", "-o", (farm.dir() / "out" / "f_####.exr").string()},
                               60s);
  std::ofstream(farm.dir() / "upload-stall.done") << "go\n";
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(py.wait(60s), 0) << py.log();
  EXPECT_TRUE(has(farm.server().log(), "--upload-idle-seconds")) << farm.server().log();
  for (const auto& e : fs::directory_iterator(farm.data_dir() / "bundles")) {
    EXPECT_EQ(e.path().filename().string().rfind(".upload-", 0), std::string::npos) << e.path();
  }
}

// Job ownership: a job belongs to the identity that submitted it.
// `tessera ARGS` for a job, returning the result.
CliResult on_job(Farm& farm, const std::vector<std::string>& args, const std::vector<std::string>& who) {
  std::vector<std::string> a = args;
  a.insert(a.end(), {"--coordinator", farm.address()});
  a.insert(a.end(), who.begin(), who.end());
  return farm.cli(a, 60s);
}

std::string submit_detached(Farm& farm, const std::vector<std::string>& who) {
  CliResult s = on_job(farm, {"submit", kScene.string(), "--frames", "0", "--detach"}, who);
  EXPECT_EQ(s.code, 0) << s.output;
  return job_id_from(s.output);
}

// The checks both identity kinds share: the other identity may not watch, acknowledge or
// cancel; the owner and an administrator may.
void expect_ownership(Farm& farm, const std::vector<std::string>& alice, const std::vector<std::string>& bob,
                      const std::string& alice_id, const std::string& bob_id,
                      const std::vector<std::string>& admin) {
  const std::string job = submit_detached(farm, alice);
  ASSERT_FALSE(job.empty());
  CliResult c = on_job(farm, {"cancel", job}, bob);
  EXPECT_EQ(c.code, 1) << c.output;
  EXPECT_TRUE(has(c.output, "PERMISSION_DENIED") || has(c.output, "belongs to " + alice_id)) << c.output;
  EXPECT_TRUE(has(c.output, "job " + job + " belongs to " + alice_id + ", and you are " + bob_id)) << c.output;
  CliResult w = on_job(farm, {"watch", job, "-o", (farm.dir() / "bob_####.exr").string()}, bob);
  EXPECT_EQ(w.code, 1) << w.output;
  EXPECT_TRUE(has(w.output, "belongs to " + alice_id)) << w.output;
  EXPECT_FALSE(fs::exists(farm.dir() / "bob_0000.exr"));
  // Status stays readable; the job is untouched.
  CliResult st = on_job(farm, {"status", job, "--json"}, bob);
  ASSERT_EQ(st.code, 0) << st.output;
  EXPECT_EQ(nlohmann::json::parse(st.output).at("state"), "queued") << st.output;
  // The owner may cancel; so may an administrator (a second job).
  EXPECT_EQ(on_job(farm, {"cancel", job}, alice).code, 0);
  const std::string job2 = submit_detached(farm, alice);
  CliResult ca = on_job(farm, {"cancel", job2}, admin);
  EXPECT_EQ(ca.code, 0) << ca.output;
  CliResult st2 = on_job(farm, {"status", job2, "--json"}, alice);
  EXPECT_EQ(nlohmann::json::parse(st2.output).at("state"), "cancelled") << st2.output;
}

TEST(FarmSecurity, NamedClientTokensOwnTheirJobs) {
  Farm farm;
  // One file, name:token per line.
  write(farm.dir() / "clients", "# the farm's clients\nalice: alice-secret-1\nbob:bob-secret-2\nops:ops-secret-3\n");
  write(farm.dir() / "alice.token", "alice-secret-1");
  write(farm.dir() / "bob.token", "bob-secret-2");
  write(farm.dir() / "ops.token", "ops-secret-3");
  farm.start_server({"--client-tokens", (farm.dir() / "clients").string(), "--admin", "token:ops"});
  const std::vector<std::string> alice{"--token-file", (farm.dir() / "alice.token").string()};
  const std::vector<std::string> bob{"--token-file", (farm.dir() / "bob.token").string()};
  const std::vector<std::string> ops{"--token-file", (farm.dir() / "ops.token").string()};
  expect_ownership(farm, alice, bob, "token:alice", "token:bob", ops);
  // No token, or an unknown one, is refused before any of that.
  CliResult none = on_job(farm, {"status"}, {});
  EXPECT_EQ(none.code, 1);
  EXPECT_TRUE(has(none.output, "requires a client token")) << none.output;

  // A directory of files NAME holding a token works the same; a bad file is named at start.
  fs::create_directories(farm.dir() / "tokdir");
  write(farm.dir() / "tokdir" / "carol", "carol-secret\n");
  write(farm.dir() / "bad-clients", "alice:a\nno-colon-here\n");
  Process bad({bin("tessera-server"), "--listen", "127.0.0.1:0", "--data-dir", (farm.dir() / "d2").string(),
               "--client-tokens", (farm.dir() / "bad-clients").string()},
              farm.dir() / "bad.log");
  EXPECT_EQ(bad.wait(20s), 2) << bad.log();
  EXPECT_TRUE(has(bad.log(), "bad-clients line 2: expected name:token")) << bad.log();
  Process dir_server({bin("tessera-server"), "--listen", "127.0.0.1:0", "--data-dir", (farm.dir() / "d3").string(),
                      "--client-tokens", (farm.dir() / "tokdir").string(), "--log-level", "info"},
                     farm.dir() / "dir.log");
  std::string addr;
  for (int i = 0; i < 400 && addr.empty(); ++i) {
    const auto at = dir_server.log().find("listening on ");
    if (at != std::string::npos && dir_server.log().find('\n', at) != std::string::npos) {
      addr = dir_server.log().substr(at + 13, dir_server.log().find('\n', at) - at - 13);
    } else {
      std::this_thread::sleep_for(25ms);
    }
  }
  ASSERT_FALSE(addr.empty()) << dir_server.log();
  write(farm.dir() / "carol.token", "carol-secret");
  CliResult carol = farm.cli({"submit", kScene.string(), "--frames", "0", "--detach", "--coordinator", addr,
                              "--token-file", (farm.dir() / "carol.token").string()});
  EXPECT_EQ(carol.code, 0) << carol.output;
  EXPECT_TRUE(has(dir_server.log(), "submitted")) << dir_server.log();
}

TEST(FarmSecurity, MutualTlsIdentitiesOwnTheirJobs) {
  Farm farm;
  const Pki pki = make_pki(farm.dir());
  farm.start_server({"--tls-cert", pki.server_cert.string(), "--tls-key", pki.server_key.string(), "--tls-ca",
                     pki.ca.string()});
  const std::vector<std::string> one{"--tls-ca", pki.ca.string(), "--tls-cert", pki.client_cert.string(),
                                     "--tls-key", pki.client_key.string()};
  const std::vector<std::string> two{"--tls-ca", pki.ca.string(), "--tls-cert", pki.client2_cert.string(),
                                     "--tls-key", pki.client2_key.string()};
  const std::string job = submit_detached(farm, one);
  CliResult c = on_job(farm, {"cancel", job}, two);
  EXPECT_EQ(c.code, 1) << c.output;
  EXPECT_TRUE(has(c.output, "job " + job + " belongs to cn:client-1, and you are cn:client-2")) << c.output;
  CliResult own = on_job(farm, {"cancel", job}, one);
  EXPECT_EQ(own.code, 0) << own.output;
}

// Limits: each refused through the real CLI, with the code's exit status and the limit's flag.
TEST(FarmSecurity, LimitsRefuseOversizedJobsNamingTheLimit) {
  Farm farm;
  farm.start_server({"--max-pixels", "5000", "--max-spp", "8", "--max-frames", "2"});
  auto submit = [&](std::vector<std::string> extra) {
    std::vector<std::string> args{"submit", kScene.string(), "--coordinator", farm.address(), "--detach"};
    args.insert(args.end(), extra.begin(), extra.end());
    return farm.cli(args);
  };
  // Resolution: 96x64 = 6144 pixels > 5000 (the scene's own size); 64x64 = 4096 passes this limit.
  CliResult r = submit({"--frames", "0-1"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_TRUE(has(r.output, "width*height) is 6144, over this coordinator's limit 5000 (tessera-server --max-pixels)"))
      << r.output;
  r = submit({"--frames", "0-1", "--width", "64", "--spp", "9"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_TRUE(has(r.output, "spp is 9, over this coordinator's limit 8 (tessera-server --max-spp)")) << r.output;
  r = submit({"--width", "64"});  // all 3 frames
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_TRUE(has(r.output, "frame count is 3, over this coordinator's limit 2 (tessera-server --max-frames)"))
      << r.output;
  // Just inside every limit: accepted.
  r = submit({"--width", "64", "--spp", "8", "--frames", "1-2"});
  EXPECT_EQ(r.code, 0) << r.output;
}

TEST(FarmSecurity, BundleSizeAndPrimitiveLimits) {
  {
    Farm farm;
    farm.start_server({"--max-bundle-bytes", "1000"});
    // The test scene's bundle is about 1.5 KB.
    CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach"});
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_TRUE(has(r.output, "over this coordinator's limit 1000 (tessera-server --max-bundle-bytes)")) << r.output;
  }
  for (const char* limit : {"3", "4"}) {
    // The scene has 4 primitives (a plane and three spheres): over a limit of 3, inside one of 4.
    Farm farm;
    farm.start_server({"--max-primitives", limit});
    CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach"});
    if (std::string(limit) == "3") {
      EXPECT_EQ(r.code, 1) << r.output;
      EXPECT_TRUE(has(r.output, "more than 3 primitives")) << r.output;
      EXPECT_TRUE(has(r.output, "(tessera-server --max-primitives)")) << r.output;
    } else {
      EXPECT_EQ(r.code, 0) << r.output;
    }
  }
}

TEST(FarmSecurity, JobsPerClientLimitCountsOnlyActiveJobs) {
  Farm farm;
  farm.start_server({"--max-jobs-per-client", "2"});  // no worker: jobs stay queued
  auto submit = [&] {
    return farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--frames", "0"});
  };
  CliResult a = submit(), b = submit();
  ASSERT_EQ(a.code, 0) << a.output;
  ASSERT_EQ(b.code, 0) << b.output;
  CliResult c = submit();
  EXPECT_EQ(c.code, 1) << c.output;
  EXPECT_TRUE(has(c.output, "active jobs of client ipv4:127.0.0.1 is 3, over this coordinator's limit 2 "
                            "(tessera-server --max-jobs-per-client)"))
      << c.output;
  // A cancelled job no longer counts.
  CliResult cancel = farm.cli({"cancel", job_id_from(a.output), "--coordinator", farm.address()});
  ASSERT_EQ(cancel.code, 0) << cancel.output;
  CliResult d = submit();
  EXPECT_EQ(d.code, 0) << d.output;
  // The count survives a coordinator restart: each job stores its owner (jobs.owner).
  farm.restart_server();
  CliResult e = submit();
  EXPECT_EQ(e.code, 1) << e.output << farm.server().log();
  EXPECT_TRUE(has(e.output, "active jobs of client ipv4:127.0.0.1 is 3, over this coordinator's limit 2")) << e.output;
}

TEST(FarmSecurity, HostileBundlesAndMessagesAreRefused) {
  Farm farm;
  farm.start_server({"--max-message-bytes", "2097152"});
  Process py({"/usr/bin/python3", source("tests/farm/security_probe.py").string(), farm.address(),
              source("proto").string(), farm.dir().string(), "message-size", "bundle-paths", "mesh-escape", "health"},
             farm.dir() / "probe.log");
  EXPECT_EQ(py.wait(60s), 0) << py.log() << farm.server().log();
  // Nothing was written outside the bundle store.
  EXPECT_FALSE(fs::exists(farm.dir() / "server-data" / "evil"));
  EXPECT_FALSE(fs::exists(farm.dir() / "evil"));
}

}  // namespace
}  // namespace tessera::farmtest

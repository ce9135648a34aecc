// Security of the farm through the real processes: tokens (per role), TLS (right CA, plaintext,
// wrong CA, client certificates) and the coordinator's limits, each refused with the right code
// and a message naming the limit. The PKI is made per test run with openssl in a temp directory.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 96x64, 4 spp, 3 frames, 4 objects

void write(const fs::path& p, const std::string& s) {
  std::ofstream(p) << s;
}

void sh(const std::string& cmd) {
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

// A throwaway CA, a server certificate for 127.0.0.1/localhost and a client certificate signed by
// it, and a second, unrelated CA. EC P-256 keys: quick to make.
struct Pki {
  fs::path dir;
  fs::path ca, server_cert, server_key, client_cert, client_key, other_ca;
};

Pki make_pki(const fs::path& dir) {
  Pki p;
  p.dir = dir / "pki";
  fs::create_directories(p.dir);
  const std::string d = p.dir.string();
  const std::string key = "-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
  write(p.dir / "server.ext", "subjectAltName=IP:127.0.0.1,DNS:localhost\n");
  write(p.dir / "client.ext", "extendedKeyUsage=clientAuth\n");
  const std::string q = " 2>>" + d + "/openssl.log";
  sh("cd " + d + " && openssl req -x509 " + key + " -keyout ca.key -out ca.pem -days 2 -subj '/CN=Tessera Test CA'" + q);
  sh("cd " + d + " && openssl req -x509 " + key + " -keyout other.key -out other-ca.pem -days 2 -subj '/CN=Other CA'" + q);
  for (const std::string who : {"server", "client"}) {
    const std::string cn = who == "server" ? "localhost" : "client-1";
    sh("cd " + d + " && openssl req " + key + " -keyout " + who + ".key -out " + who + ".csr -subj '/CN=" + cn + "'" + q);
    sh("cd " + d + " && openssl x509 -req -in " + who + ".csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 2 -out " +
       who + ".pem -extfile " + who + ".ext" + q);
  }
  p.ca = p.dir / "ca.pem";
  p.other_ca = p.dir / "other-ca.pem";
  p.server_cert = p.dir / "server.pem";
  p.server_key = p.dir / "server.key";
  p.client_cert = p.dir / "client.pem";
  p.client_key = p.dir / "client.key";
  return p;
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
  // Plaintext to a TLS port: the handshake never completes, nothing is answered.
  EXPECT_EQ(count_workers(farm, {"--token-file", t.client.string()}, &out), -1);
  EXPECT_TRUE(has(out, "cannot reach the coordinator")) << out;
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

// SPDX-License-Identifier: Apache-2.0
// `tessera rays` and tessera-rays as processes: in-process and service answers identical byte for
// byte (CSV and .npy, several batches), analytic values in the CSV, bad input exits 2 naming the
// ray, tokens on both hops, the Python example client built from ray_service.proto alone, and a
// connection flood at the hard descriptor limit.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <thread>

#include "../farm/test_pki.h"
#include "farm/bundle.h"
#include "rays_harness.h"
#include "scene/scene_parser.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

TEST(RaysCli, InProcessAndServiceAnswersAreIdentical) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays);
  const fs::path in = farm.dir() / "rays.csv";
  write_bunny_rays(in, 3000);
  const std::string scene = source("scenes/bunny.json").string();
  for (const char* ext : {".csv", ".npy"}) {
    const fs::path local = farm.dir() / (std::string("local") + ext), remote = farm.dir() / (std::string("remote") + ext);
    CliResult r = farm.cli({"rays", scene, "--in", in.string(), "--out", local.string()});
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("3000 rays"), std::string::npos) << r.output;
    // 7 batches of 450 (the last one short) on one stream.
    r = farm.cli({"rays", scene, "--in", in.string(), "--out", remote.string(), "--server", addr, "--coordinator",
                  farm.address(), "--batch", "450"});
    ASSERT_EQ(r.code, 0) << r.output << rays->log();
    ASSERT_EQ(read_text(local), read_text(remote)) << ext;
  }
  // Mostly hits, some misses: the comparison covered both.
  const std::string csv = read_text(farm.dir() / "local.csv");
  size_t hits = 0, lines = 0;
  for (size_t at = csv.find('\n'); at != std::string::npos && at + 1 < csv.size(); at = csv.find('\n', at + 1)) {
    ++lines;
    hits += csv.compare(csv.find(',', at + 1) + 1, 2, "1,") == 0;
  }
  EXPECT_EQ(lines, 3000u);
  EXPECT_GT(hits, 1000u);
  EXPECT_LT(hits, 3000u);
}

// tessera-rays under a hard limit of 200 descriptors takes 300 connections that send nothing,
// held 3 s: it sheds what it cannot take (farm/accept_guard.h) and answers again afterwards, the
// same answers as in-process. Without the guard gRPC 1.51 stops accepting for good.
TEST(RaysService, AConnectionFloodAtTheHardLimitDoesNotStopIt) {
  rlim_t hard = 0;
  if (!own_descriptors(1024, &hard)) GTEST_SKIP() << "this test needs 1024 descriptors, the hard limit is " << hard;
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays);
  ASSERT_FALSE(addr.empty());
  Process prlimit({"/usr/bin/prlimit", "--pid", std::to_string(rays->pid()), "--nofile=200:200"},
                  farm.dir() / "prlimit.log");
  ASSERT_EQ(prlimit.wait(10s), 0) << prlimit.log();
  {
    const std::vector<int> flood = silent_connections(std::stoi(addr.substr(addr.rfind(':') + 1)), 300);
    ASSERT_EQ(flood.size(), 300u) << std::strerror(errno);
    std::this_thread::sleep_for(3s);
    for (int fd : flood) close(fd);
  }
  EXPECT_NE(rays->log().find("out of descriptors"), std::string::npos) << rays->log();
  const fs::path in = farm.dir() / "rays.csv", local = farm.dir() / "local.csv", remote = farm.dir() / "remote.csv";
  write_bunny_rays(in, 300);
  const std::string scene = source("scenes/bunny.json").string();
  CliResult r = farm.cli({"rays", scene, "--in", in.string(), "--out", local.string()});
  ASSERT_EQ(r.code, 0) << r.output;
  r = farm.cli({"rays", scene, "--in", in.string(), "--out", remote.string(), "--server", addr, "--coordinator",
                farm.address()});
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  EXPECT_EQ(read_text(local), read_text(remote));
}

// The CSV's rows as cells, by column name (no quoted cells here: the bunny's names have no commas).
std::map<std::string, std::vector<std::string>> csv_columns(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  for (std::istringstream h(line); std::getline(h, line, ',');) names.push_back(line);
  std::map<std::string, std::vector<std::string>> columns;
  while (std::getline(in, line)) {
    size_t k = 0;
    std::string cell;
    for (std::istringstream row(line + ","); std::getline(row, cell, ',');) columns[names.at(k++)].push_back(cell);
  }
  return columns;
}

// --fields t,object: the service sends hit, t and object alone, and the output has exactly
// those columns (and id), with the full run's values; in-process it selects the same columns,
// byte for byte. A bad name, and --fields with --occlusion, exit 2 naming the flag.
TEST(RaysCli, FieldsWritesOnlyTheChosenColumnsWithTheFullRunsValues) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays, {"--log-level", "debug"});
  const fs::path in = farm.dir() / "rays.csv";
  write_bunny_rays(in, 1000);
  const std::string scene = source("scenes/bunny.json").string();
  auto run = [&](const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> args{"rays", scene, "--in", in.string(), "--out", (farm.dir() / out).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    return farm.cli(args);
  };
  const std::vector<std::string> remote{"--server", addr, "--coordinator", farm.address(), "--batch", "300"};
  std::vector<std::string> remote_t_object = remote;
  remote_t_object.insert(remote_t_object.end(), {"--fields", "t,object"});
  CliResult r = run("full.csv", remote);
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  for (const char* ext : {".csv", ".npy"}) {
    r = run(std::string("remote") + ext, remote_t_object);
    ASSERT_EQ(r.code, 0) << r.output << rays->log();
    r = run(std::string("local") + ext, {"--fields", "object,t,object"});
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(read_text(farm.dir() / (std::string("remote") + ext)), read_text(farm.dir() / (std::string("local") + ext)))
        << ext;
  }
  // The mask went over the wire (the files alone would look the same if the client asked for
  // every field): the server's log names what each batch asked for.
  const std::string log = rays->log();
  EXPECT_NE(log.find("batch of 300 rays: nearest hits, fields t,point,normal,shading_normal,barycentrics,object,"
                     "primitive,material"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("batch of 300 rays: nearest hits, fields t,object\n"), std::string::npos) << log;
  const std::string masked = read_text(farm.dir() / "remote.csv");
  ASSERT_EQ(masked.substr(0, masked.find('\n')), "id,hit,t,object");
  auto got = csv_columns(masked), want = csv_columns(read_text(farm.dir() / "full.csv"));
  ASSERT_EQ(got.size(), 4u);
  for (const char* column : {"id", "hit", "t", "object"}) EXPECT_EQ(got[column], want[column]) << column;
  EXPECT_EQ(got["t"].size(), 1000u);
  EXPECT_GT(std::count(got["hit"].begin(), got["hit"].end(), "1"), 100);  // hits and misses both
  EXPECT_GT(std::count(got["hit"].begin(), got["hit"].end(), "0"), 100);
  const std::string npy = read_text(farm.dir() / "remote.npy");
  EXPECT_NE(npy.find("'descr': [('id', '<u8'), ('hit', 'u1'), ('t', '<f4'), ('object', 'S"), std::string::npos)
      << npy.substr(0, 200);

  // Without ids: exactly hit, t, object.
  const fs::path small = farm.dir() / "small.csv";
  std::ofstream(small) << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n0,0,0,0,1,0\n";
  r = farm.cli({"rays", source("tests/rays/sphere_scene.json").string(), "--in", small.string(), "--out",
                (farm.dir() / "small-out.csv").string(), "--fields", "object,t", "--server", addr, "--coordinator",
                farm.address()});
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  EXPECT_EQ(read_text(farm.dir() / "small-out.csv"), "hit,t,object\n1,8,ball\n0,inf,\n");

  r = run("bad.csv", {"--fields", "t,pointz", "--server", addr, "--coordinator", farm.address()});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--fields: 'pointz' is not a hit field (allowed: "
                          "t,point,normal,shading_normal,barycentrics,object,primitive,material)"),
            std::string::npos)
      << r.output;
  r = run("occ.csv", {"--fields", "t", "--occlusion"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--fields chooses the columns of nearest hits; --occlusion answers hit alone"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(farm.dir() / "bad.csv"));
  EXPECT_FALSE(fs::exists(farm.dir() / "occ.csv"));
}

// A ray server that stops answering (here: stopped with SIGSTOP, its socket still open) ends
// the run at --timeout with a message naming it, rather than hanging the client.
TEST(RaysCli, AServerThatStopsAnsweringEndsTheRunAtTheTimeout) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays, {"--no-announce"});
  const fs::path in = farm.dir() / "rays.csv";
  write_bunny_rays(in, 200);
  const std::string scene = source("scenes/bunny.json").string();
  // Once answering (the scene loaded), then stopped.
  CliResult r = farm.cli({"rays", scene, "--in", in.string(), "--out", (farm.dir() / "a.csv").string(), "--server",
                          addr, "--coordinator", farm.address()});
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  ASSERT_EQ(kill(rays->pid(), SIGSTOP), 0);
  const auto t0 = std::chrono::steady_clock::now();
  r = farm.cli({"rays", scene, "--in", in.string(), "--out", (farm.dir() / "b.csv").string(), "--server", addr,
                "--coordinator", farm.address(), "--timeout", "3"});
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  kill(rays->pid(), SIGCONT);
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("--timeout"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(addr), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(farm.dir() / "b.csv"));  // nothing written over a missing answer
  EXPECT_LT(took, 60.0);  // not a wall-clock assertion on speed: only that it did not hang
}

TEST(RaysCli, CsvCarriesTheAnalyticHit) {
  Farm farm;
  const fs::path in = farm.dir() / "in.csv", out = farm.dir() / "out.csv";
  std::ofstream(in) << "ox,oy,oz,dx,dy,dz,tmin,tmax\n0,0,0,0,0,5,0,inf\n0,0,0,0,-1,0,0,2.5\n0,0,0,0,0,1,9,inf\n";
  const CliResult r = farm.cli({"rays", source("tests/rays/sphere_scene.json").string(), "--in", in.string(), "--out",
                                out.string()});
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(read_text(out),
            "hit,t,px,py,pz,nx,ny,nz,snx,sny,snz,u,v,object,primitive,material\n"
            "1,8,0,0,8,0,0,-1,0,0,-1,0,0,ball,0,red\n"      // the sphere's near side
            "0,inf,0,0,0,0,0,0,0,0,0,0,0,,,\n"               // the floor is 3 away: past t_max
            "1,12,0,0,12,0,0,1,-0,-0,-1,0,0,ball,0,red\n");  // from t_min = 9, inside: the far side
  // (the shading normal is the negated outward normal, signed zeros and all: bits as computed)
}

TEST(RaysCli, BadInputExitsTwoNamingTheRayAndField) {
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays, {"--max-batch-rays", "100"});
  const std::string scene = source("tests/rays/sphere_scene.json").string();
  const fs::path bad = farm.dir() / "bad.csv", many = farm.dir() / "many.csv";
  std::ofstream(bad) << "ox,oy,oz,dx,dy,dz,tmin,tmax\n0,0,0,0,0,1,0,1\n0,0,0,0,0,1,3,2\n";
  CliResult r = farm.cli({"rays", scene, "--in", bad.string(), "--out", (farm.dir() / "x.csv").string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("ray 1: t_min > t_max"), std::string::npos) << r.output;
  std::ofstream(bad) << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n0,0,0,nan,0,1\n";
  r = farm.cli({"rays", scene, "--in", bad.string(), "--out", (farm.dir() / "x.csv").string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("ray 1: direction is not finite"), std::string::npos) << r.output;
  {
    std::ofstream m(many);
    m << "ox,oy,oz,dx,dy,dz\n";
    for (int i = 0; i < 150; ++i) m << "0,0,0,0,0,1\n";
  }
  r = farm.cli({"rays", scene, "--in", many.string(), "--out", (farm.dir() / "x.csv").string(), "--server", addr,
                "--coordinator", farm.address(), "--batch", "150"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("batch 0: batch of 150 rays (directions / 3) is over this server's limit 100"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(rays->running());  // refused, not crashed
}

TEST(RaysCli, TokensOnBothHops) {
  Farm farm;
  std::ofstream(farm.dir() / "client.token") << "client-secret\n";
  std::ofstream(farm.dir() / "worker.token") << "worker-secret\n";
  const std::string client_token = (farm.dir() / "client.token").string();
  const std::string worker_token = (farm.dir() / "worker.token").string();
  farm.start_server({"--client-token-file", client_token, "--worker-token-file", worker_token});
  std::unique_ptr<Process> rays;
  const std::string addr =
      start_rays(farm, &rays, {"--client-token-file", client_token, "--worker-token-file", worker_token});
  const fs::path in = farm.dir() / "in.csv";
  std::ofstream(in) << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n";
  const std::string scene = source("tests/rays/sphere_scene.json").string();
  const std::vector<std::string> args{"rays", scene, "--in", in.string(), "--out", (farm.dir() / "o.csv").string(),
                                      "--server", addr, "--coordinator", farm.address()};
  CliResult r = farm.cli(args);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("client token"), std::string::npos) << r.output;
  std::vector<std::string> with_token = args;
  with_token.insert(with_token.end(), {"--token-file", client_token});
  r = farm.cli(with_token);
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  EXPECT_EQ(read_text(farm.dir() / "o.csv").substr(read_text(farm.dir() / "o.csv").find('\n') + 1, 4), "1,8,");
}

// TLS on both hops of tessera-rays: clients to it, and it to the coordinator for bundles. The
// right CA answers; plaintext, a wrong CA on either hop, and a wrong CA at the client fail.
TEST(RaysCli, TlsOnBothHops) {
  Farm farm;
  const Pki pki = make_pki(farm.dir());
  const std::vector<std::string> server_tls{"--tls-cert", pki.server_cert.string(), "--tls-key",
                                            pki.server_key.string()};
  farm.start_server(server_tls);
  std::vector<std::string> rays_args = server_tls;
  rays_args.insert(rays_args.end(), {"--coordinator-tls-ca", pki.ca.string()});
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays, rays_args);
  const fs::path in = farm.dir() / "in.csv";
  std::ofstream(in) << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n";
  const std::string scene = source("tests/rays/sphere_scene.json").string();
  auto query = [&](const std::string& server, const std::vector<std::string>& tls) {
    std::vector<std::string> args{"rays", scene, "--in", in.string(), "--out", (farm.dir() / "o.csv").string(),
                                  "--server", server, "--coordinator", farm.address()};
    args.insert(args.end(), tls.begin(), tls.end());
    fs::remove(farm.dir() / "o.csv");
    return farm.cli(args);
  };
  // tessera-rays trusting another CA for the coordinator cannot fetch the bundle: the query fails.
  std::unique_ptr<Process> lost;
  std::vector<std::string> lost_args = server_tls;
  lost_args.insert(lost_args.end(), {"--coordinator-tls-ca", pki.other_ca.string()});
  const std::string lost_addr = start_rays(farm, &lost, lost_args, "lost");
  CliResult r = query(lost_addr, {"--tls-ca", pki.ca.string()});
  EXPECT_EQ(r.code, 1) << r.output << lost->log();
  EXPECT_FALSE(fs::exists(farm.dir() / "o.csv"));
  // Clients: the right CA answers, plaintext and another CA do not.
  r = query(addr, {"--tls-ca", pki.ca.string()});
  ASSERT_EQ(r.code, 0) << r.output << rays->log();
  EXPECT_EQ(read_text(farm.dir() / "o.csv").substr(read_text(farm.dir() / "o.csv").find('\n') + 1, 4), "1,8,");
  r = query(addr, {});
  EXPECT_EQ(r.code, 1) << "plaintext to TLS servers answered: " << r.output;
  r = query(addr, {"--tls-ca", pki.other_ca.string()});
  EXPECT_EQ(r.code, 1) << "a server certificate from another CA was trusted: " << r.output;
  EXPECT_FALSE(fs::exists(farm.dir() / "o.csv"));
  EXPECT_TRUE(rays->running());
  EXPECT_TRUE(lost->running());
}

TEST(RaysPython, ExampleClientFromTheProtoAlone) {
  if (!fs::exists("/usr/bin/python3")) GTEST_SKIP() << "/usr/bin/python3 not installed";
  Farm farm;
  farm.start_server();
  std::unique_ptr<Process> rays;
  const std::string addr = start_rays(farm, &rays);
  // Upload the bundle the way any client would (here: the CLI), then hand its hash to Python.
  const fs::path scene = source("tests/rays/sphere_scene.json"), in = farm.dir() / "in.csv";
  std::ofstream(in) << "ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n";
  CliResult r = farm.cli({"rays", scene.string(), "--in", in.string(), "--out", (farm.dir() / "o.csv").string(),
                          "--server", addr, "--coordinator", farm.address()});
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string sha = farm::make_bundle(scene, {}).sha256;
  Process py({"/usr/bin/python3", source("docs/examples/rays_client.py").string(), addr, source("proto").string(), sha},
             farm.dir() / "python.log");
  ASSERT_EQ(py.wait(120s), 0) << py.log();
  const std::string log = py.log();
  for (const char* want : {"objects: ball (sphere), floor (plane)", "ray 0: hit ball t=8 p=[0.0, 0.0, 8.0] n=[0.0, 0.0, -1.0]",
                           "ray 1: hit floor t=3 p=[0.0, -3.0, 0.0]", "ray 2: miss",
                           "t only: [1, 1, 0] [8.0, 3.0, inf] points sent: 0", "occluded: [0, 1]",
                           "bad batch refused: INVALID_ARGUMENT ray 1: direction is zero-length (field direction)"}) {
    EXPECT_NE(log.find(want), std::string::npos) << want << "\n" << log;
  }
  // An unknown hash: the service names the field.
  Process unknown({"/usr/bin/python3", source("docs/examples/rays_client.py").string(), addr, source("proto").string(),
                   std::string(64, 'e')},
                  farm.dir() / "python-unknown.log");
  EXPECT_NE(unknown.wait(120s), 0);
  EXPECT_NE(unknown.log().find("scene.bundle_sha256: unknown bundle eeee"), std::string::npos) << unknown.log();
}

}  // namespace
}  // namespace tessera::farmtest

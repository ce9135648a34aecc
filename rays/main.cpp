// SPDX-License-Identifier: Apache-2.0
// tessera-rays: the ray service (docs/rays.md). Answers nearest-hit and line-of-sight queries on
// scene bundles uploaded to the coordinator, which it fetches like a worker does, and announces
// itself to the coordinator so that clients can find it (announcer.h).
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <thread>

#include "announcer.h"
#include "bundle_scenes.h"
#include "farm/accept_guard.h"
#include "farm/auth.h"
#include "farm/command_line.h"
#include "farm/bundle_fetch.h"
#include "farm/channel.h"
#include "farm/request_limits.h"
#include "farm/server_connections.h"
#include "farm/stop_signals.h"
#include "large_buffers.h"
#include "ray_service.h"
#include "render/embree_device.h"

using namespace tessera;

namespace {

constexpr const char* kVersion = "tessera-rays 0.1.0";

// Everything the command line sets, with its defaults (some from the environment and the machine).
struct RaysFlags {
  std::string listen = "127.0.0.1:7879";
  std::string coordinator = farm::kDefaultCoordinator;
  std::string cache = (std::filesystem::temp_directory_path() / "tessera-rays-cache").string();
  std::string log_level = "info";
  rayserver::RayServiceOptions options;
  int64_t max_message_bytes = farm::Limits{}.max_message_bytes;
  int max_frames = 8;
  std::string advertise;
  double announce_seconds = 5;
  bool no_announce = false;
  farm::ServerSecurity inbound;  // from clients
  std::string worker_token_file;   // to the coordinator, as a worker
  farm::ChannelSecurity outbound;

  RaysFlags() {
    if (const char* env = std::getenv("TESSERA_COORDINATOR"); env && *env) coordinator = env;
    options.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  }
};

// nullopt to go on; else the exit code (--help, --version, a malformed command line).
std::optional<int> parse_flags(int argc, char** argv, RaysFlags& f) {
  CLI::App app{"tessera-rays: nearest-hit and line-of-sight queries over gRPC (tessera.v1.RayService)"};
  app.add_option("--listen", f.listen, "HOST:PORT to serve on (port 0 picks a free one)")->capture_default_str();
  app.add_option("--coordinator", f.coordinator,
                 "Coordinator HOST:PORT the scene bundles come from (env TESSERA_COORDINATOR)")
      ->capture_default_str();
  app.add_option("--threads", f.options.threads,
                 "Threads large batches (over 2048 rays) are split across, all requests together (smaller ones "
                 "run on the thread that received them)")
      ->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--cache-dir", f.cache, "Where fetched scene bundles are kept")->capture_default_str();
  app.add_option("--max-frames", f.max_frames, "Built frames (Embree scenes) kept in memory")
      ->check(CLI::Range(1, 1024))->capture_default_str();
  app.add_option("--log-level", f.log_level, "trace, debug, info, warn, error")->capture_default_str();
  // Discovery (docs/rays.md): the coordinator lists this server to clients while it announces itself.
  app.add_option("--advertise", f.advertise,
                 "HOST[:PORT] clients should dial, announced to the coordinator (default: the --listen host and the "
                 "bound port; required when --listen is 0.0.0.0 or [::])")
      ->group("Discovery");
  app.add_option("--announce-seconds", f.announce_seconds,
                 "Announce this server to the coordinator this often; it is listed until 3 periods pass without one")
      ->check(CLI::Range(0.1, 300.0))->capture_default_str()->group("Discovery");
  app.add_flag("--no-announce", f.no_announce,
               "Do not announce this server: clients must name it with --server (standalone use)")
      ->group("Discovery");
  // Inbound: the same flags, files and environment variables as tessera-server's client side.
  app.add_option("--client-token-file", f.inbound.client_token_file,
                 "File holding the token clients must send (else env TESSERA_CLIENT_TOKEN; none: open)")
      ->group("Security");
  app.add_option("--tls-cert", f.inbound.tls_cert, "PEM certificate of this server: TLS on every connection")
      ->group("Security");
  app.add_option("--tls-key", f.inbound.tls_key, "PEM private key of --tls-cert")->group("Security");
  app.add_option("--tls-ca", f.inbound.tls_ca, "PEM CA: also require client certificates signed by it (mutual TLS)")
      ->group("Security");
  // Outbound: to the coordinator, as a worker (bundles are fetched with the worker token).
  app.add_option("--worker-token-file", f.worker_token_file,
                 "File holding the coordinator's worker token (else env TESSERA_WORKER_TOKEN)")
      ->group("Security");
  app.add_option("--coordinator-tls-ca", f.outbound.tls_ca, "PEM CA certificate of the coordinator: connect with TLS")
      ->group("Security");
  app.add_option("--coordinator-tls-cert", f.outbound.tls_cert, "PEM client certificate for the coordinator")
      ->group("Security");
  app.add_option("--coordinator-tls-key", f.outbound.tls_key, "PEM private key of --coordinator-tls-cert")
      ->group("Security");
  app.add_option("--max-message-bytes", f.max_message_bytes, "Largest gRPC message accepted")
      ->check(CLI::Range(int64_t(2) << 20, int64_t(1) << 30))->capture_default_str()->group("Limits");
  app.add_option("--max-batch-rays", f.options.max_batch_rays, "Most rays in one request (larger: INVALID_ARGUMENT)")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 24))->capture_default_str()->group("Limits");
  app.set_version_flag("--version", kVersion);
  return farm::parse_command_line(app, argc, argv);
}

// Builds and starts the gRPC server; null when it cannot listen. `*port` is the port bound.
std::unique_ptr<grpc::Server> start_grpc_server(const RaysFlags& f,
                                                const std::shared_ptr<grpc::ServerCredentials>& credentials,
                                                rayserver::RayServiceImpl& service, int* port) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  builder.AddListeningPort(f.listen, credentials, port);
  builder.RegisterService(&service);
  builder.SetMaxReceiveMessageSize(int(f.max_message_bytes));
  builder.SetMaxSendMessageSize(int(f.max_message_bytes));
  // As the coordinator: keepalive pings accepted, a connection that has not finished its
  // handshake in 10 s gives its descriptor back, and running out of descriptors sheds
  // connections instead of ending the listener (farm/accept_guard.h).
  farm::set_server_connection_args(builder);
  farm::install_accept_guard();
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || *port == 0) return nullptr;
  return server;
}

// Announces this server to the coordinator every --announce-seconds, with the service's counters;
// null (and said) with --no-announce.
std::unique_ptr<rayserver::Announcer> start_announcer(const RaysFlags& f, const farm::Authenticator& auth,
                                                      v1::WorkerService::Stub& stub,
                                                      rayserver::RayServiceImpl& service,
                                                      const std::string& advertised) {
  if (f.no_announce) {
    spdlog::info("not announced to the coordinator (--no-announce): clients must name this server with --server");
    return nullptr;
  }
  v1::RayServerDescription self;
  self.set_server_id(rayserver::new_server_id());
  self.set_address(advertised);
  self.set_threads(f.options.threads);
  self.set_embree_isa(embree_isa());
  self.set_max_batch_rays(f.options.max_batch_rays);
  self.set_tls(!f.inbound.tls_cert.empty());
  self.set_client_token(!auth.open(farm::PeerRole::kClient));
  self.set_version(kVersion);
  spdlog::info("announcing {} as ray server {} to the coordinator every {} s", advertised, self.server_id(),
               f.announce_seconds);
  return std::make_unique<rayserver::Announcer>(
      stub, f.coordinator, std::chrono::milliseconds(int64_t(f.announce_seconds * 1000)), [&service, self] {
        v1::RayServerDescription d = self;
        const rayserver::RayServiceCounters c = service.counters();
        d.set_requests(c.requests);
        d.set_rays(c.rays);
        d.set_rays_in_flight(c.rays_in_flight);
        return d;
      });
}

}  // namespace

int main(int argc, char** argv) {
  const sigset_t sigs = farm::block_stop_signals();  // first: gRPC's threads start with the credentials
  rayserver::keep_large_buffers();
  RaysFlags flags;
  if (std::optional<int> exit_code = parse_flags(argc, argv, flags)) return *exit_code;

  farm::Authenticator auth;
  std::shared_ptr<grpc::ServerCredentials> credentials;
  try {
    auth = farm::Authenticator(farm::read_token(flags.inbound.client_token_file, "TESSERA_CLIENT_TOKEN"), "");
    credentials = flags.inbound.credentials();
    flags.outbound.token = farm::read_token(flags.worker_token_file, "TESSERA_WORKER_TOKEN");
  } catch (const std::exception& e) {
    std::cerr << "tessera-rays: " << e.what() << "\n";
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(flags.log_level));
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ [rays] %v");

  std::unique_ptr<v1::WorkerService::Stub> stub;
  std::unique_ptr<rayserver::BundleScenes> scenes;
  try {
    stub = v1::WorkerService::NewStub(farm::make_coordinator_channel(flags.coordinator, flags.outbound));
    scenes = std::make_unique<rayserver::BundleScenes>(
        flags.cache, [&](const std::string& sha256) { return farm::fetch_bundle(*stub, sha256); },
        size_t(flags.max_frames));
  } catch (const std::exception& e) {
    std::cerr << "tessera-rays: " << e.what() << "\n";
    return 1;
  }
  if (!flags.no_announce) {
    try {
      rayserver::advertised_address(flags.listen, flags.advertise, 0);  // refuses a wildcard --listen before it is bound
    } catch (const std::invalid_argument& e) {
      std::cerr << "tessera-rays: " << e.what() << "\n";
      return 2;
    }
  }
  rayserver::RayServiceImpl service(scenes->source(), auth, flags.options);

  int port = 0;
  std::unique_ptr<grpc::Server> server = start_grpc_server(flags, credentials, service, &port);
  if (!server) {
    std::cerr << "tessera-rays: cannot listen on " << flags.listen << "\n";
    return 1;
  }
  const std::string advertised =
      flags.no_announce ? "" : rayserver::advertised_address(flags.listen, flags.advertise, port);
  const std::string host = flags.listen.substr(0, flags.listen.rfind(':'));
  spdlog::info("{}: bundles from {}, {} threads per batch, at most {} rays per batch, Embree {}", kVersion,
               flags.coordinator, flags.options.threads, flags.options.max_batch_rays, embree_isa());
  spdlog::info("security: {}, clients {}", flags.inbound.tls_cert.empty() ? "plaintext" : "TLS",
               auth.open(farm::PeerRole::kClient) ? "open" : "need the client token");
  std::printf("listening on %s:%d\n", host.c_str(), port);  // the line tests and scripts wait for
  std::fflush(stdout);
  std::unique_ptr<rayserver::Announcer> announcer = start_announcer(flags, auth, *stub, service, advertised);

  spdlog::info("signal {}: shutting down", farm::wait_for_signal(sigs));
  announcer.reset();
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  server->Wait();
  return 0;
}

// tessera-server: the farm's coordinator. Holds jobs and bundles, leases tiles to workers,
// streams finished tiles to clients.
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "bundle_store.h"
#include "client_service.h"
#include "coordinator.h"
#include "worker_service.h"

int main(int argc, char** argv) {
  using namespace tessera::server;
  std::string listen = "127.0.0.1:7878";
  std::string data_dir = "tessera-data";
  std::string log_level = "info";
  int heartbeat_ms = 1000;
  int lease_timeout_ms = 10000;
  bool no_speculation = false;

  CLI::App app{"tessera-server: the Tessera render farm coordinator"};
  app.add_option("--listen", listen, "HOST:PORT to listen on (port 0 picks a free one; 0.0.0.0 for all interfaces)")
      ->capture_default_str();
  app.add_option("--data-dir", data_dir, "Directory for scene bundles")->capture_default_str();
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  app.add_option("--heartbeat-ms", heartbeat_ms, "Heartbeat interval asked of workers")
      ->check(CLI::Range(50, 60000))->capture_default_str();
  app.add_option("--lease-timeout-ms", lease_timeout_ms, "Silence after which a worker loses its tiles")
      ->check(CLI::Range(200, 3600000))->capture_default_str();
  app.add_flag("--no-speculation", no_speculation, "Never hand out second copies of in-flight tiles");
  app.set_version_flag("--version", "tessera-server 0.1.0");
  CLI11_PARSE(app, argc, argv);

  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");

  // Signals are taken by one thread with sigwait: block them before any thread starts.
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);

  std::unique_ptr<BundleStore> store;
  try {
    store = std::make_unique<BundleStore>(data_dir);
  } catch (const std::exception& e) {
    std::cerr << "tessera-server: " << e.what() << "\n";
    return 1;
  }
  CoordinatorOptions opts;
  opts.heartbeat_interval = std::chrono::milliseconds(heartbeat_ms);
  opts.scheduler.lease_timeout = std::chrono::milliseconds(lease_timeout_ms);
  opts.scheduler.speculate = !no_speculation;
  Coordinator coordinator(opts, *store);
  ClientServiceImpl client_service(coordinator);
  WorkerServiceImpl worker_service(coordinator);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(listen, grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&client_service);
  builder.RegisterService(&worker_service);
  builder.SetMaxReceiveMessageSize(64 << 20);  // a 256x256 tile is 1 MiB; bundles come in 1 MiB chunks
  // Clients and workers ping to keep long-lived streams honest; accept their pings.
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 5000);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::cerr << "tessera-server: cannot listen on " << listen << " (address in use or not local?)\n";
    return 1;
  }
  const std::string host = listen.substr(0, listen.rfind(':'));
  spdlog::info("tessera-server 0.1.0: data in {}, heartbeat {} ms, lease timeout {} ms", data_dir, heartbeat_ms,
               lease_timeout_ms);
  // The machine-readable line tests and scripts wait for.
  std::printf("listening on %s:%d\n", host.c_str(), port);
  std::fflush(stdout);

  int sig = 0;
  sigwait(&sigs, &sig);
  spdlog::info("signal {}: shutting down", sig);
  coordinator.stop();
  // Give streams a moment to finish; then everything still open is cancelled.
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  server->Wait();
  spdlog::info("stopped");
  return 0;
}

// SPDX-License-Identifier: Apache-2.0
// tessera-server: the farm's coordinator. Holds jobs and bundles, leases tiles to workers,
// streams finished tiles to clients.
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>
#include <sys/resource.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <optional>

#include "bundle_store.h"
#include "client_service.h"
#include "coordinator.h"
#include "farm/accept_guard.h"
#include "farm/auth.h"
#include "farm/channel.h"
#include "farm/command_line.h"
#include "farm/request_limits.h"
#include "farm/server_connections.h"
#include "farm/stop_signals.h"
#include "job_store.h"
#include "metrics/farm_metrics.h"
#include "monitor/http_listener.h"
#include "monitor/monitor_feed.h"
#include "monitor/monitor_routes.h"
#include "worker_service.h"

using namespace tessera::server;
namespace farm = tessera::farm;

namespace {

// Everything the command line sets.
struct ServerFlags {
  std::string listen = farm::kDefaultCoordinator;
  std::string data_dir = "tessera-data";
  std::string log_level = "info";
  int heartbeat_ms = 1000;
  int lease_timeout_ms = 10000;
  int stall_timeout_ms = int(tessera::server::SchedulerOptions{}.stall_timeout.count());
  bool no_speculation = false;
  int max_span_tiles = tessera::server::SchedulerOptions{}.max_span_tiles;
  int span_ms = int(tessera::server::SchedulerOptions{}.span_seconds * 1000);
  int max_faults = 3;
  double retention_hours = 24;
  double max_undelivered_gb = 100;
  int delivery_lease_s = 120;
  size_t watch_backlog_tiles = CoordinatorOptions{}.watch_backlog_tiles;
  int commit_window_ms = int(tessera::server::JobStore::kDefaultCommitWindow.count());
  std::string http_listen;
  farm::ServerSecurity security;
  std::vector<std::string> admins;
  farm::Limits limits;
};

// nullopt to go on; else the exit code (--help, --version, a malformed command line).
std::optional<int> parse_flags(int argc, char** argv, ServerFlags& f) {
  CLI::App app{"tessera-server: the Tessera render farm coordinator"};
  app.add_option("--listen", f.listen, "HOST:PORT to listen on (port 0 picks a free one; 0.0.0.0 for all interfaces)")
      ->capture_default_str();
  app.add_option("--data-dir", f.data_dir,
                 "Directory for scene bundles, the job database (tessera.db) and finished tiles")
      ->capture_default_str();
  app.add_option("--log-level", f.log_level, "trace, debug, info, warn, error")->capture_default_str();
  app.add_option("--heartbeat-ms", f.heartbeat_ms, "Heartbeat interval asked of workers")
      ->check(CLI::Range(50, 60000))->capture_default_str();
  app.add_option("--lease-timeout-ms", f.lease_timeout_ms, "Silence after which a worker loses its tiles")
      ->check(CLI::Range(200, 3600000))->capture_default_str();
  app.add_option("--stall-timeout-ms", f.stall_timeout_ms,
                 "A worker that holds tiles and returns no result for this long (or 8x the slowest tile so far) "
                 "loses them, heartbeats or not")
      ->check(CLI::Range(200, 86400000))->capture_default_str();
  app.add_flag("--no-speculation", f.no_speculation, "Never hand out second copies of in-flight tiles");
  app.add_option("--max-span-tiles", f.max_span_tiles,
                 "Most tiles in one lease (consecutive tiles of a frame); 1: a lease a tile")
      ->check(CLI::Range(1, tessera::server::Lease::kMaxTiles))->capture_default_str();
  app.add_option("--span-ms", f.span_ms, "Render time a lease of several tiles aims at, at the worker's own rate")
      ->check(CLI::Range(1, 60000))->capture_default_str();
  app.add_option("--max-faults", f.max_faults, "Bad results after which a worker gets no more tiles of that job")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--retention-hours", f.retention_hours,
                 "Ended jobs whose frames no client took leave memory after this long (they stay in the database); "
                 "finished frames of jobs with a recorded output (submit -o) stay until delivered")
      ->check(CLI::Range(0.0, 24.0 * 3650))->capture_default_str();
  app.add_option("--max-undelivered-gb", f.max_undelivered_gb,
                 "Refuse new jobs while finished frames of jobs with a recorded output, not yet delivered by "
                 "`tessera collect` or `tessera watch`, take this many GB of encoded tiles (0: no limit)")
      ->check(CLI::Range(0.0, 1e9))->capture_default_str();
  app.add_option("--delivery-lease-s", f.delivery_lease_s,
                 "A deliverer that received a whole frame and has not acknowledged it after this many seconds "
                 "loses it to another deliverer of the job")
      ->check(CLI::Range(1, 86400))->capture_default_str();
  app.add_option("--watch-backlog-tiles", f.watch_backlog_tiles,
                 "Hold a job (no new leases) while one of its watch streams has this many tiles unsent; "
                 "bounds the coordinator's memory for slow clients (0: no bound)")
      ->check(CLI::Range(size_t(0), size_t(1) << 24))->capture_default_str();
  app.add_option("--commit-window-ms", f.commit_window_ms,
                 "How long finished tiles gather before one durable write takes them all (0: a write as "
                 "soon as one is queued; longer: fewer syncs per tile, more tiles rendered again after a crash)")
      ->check(CLI::Range(0, 10000))->capture_default_str();
  app.add_option("--http-listen", f.http_listen,
                 "HOST:PORT for the web monitor, its JSON API and Prometheus /metrics (off unless given; "
                 "HTTPS with the --tls-cert certificate when TLS is on; port 0 picks a free one)");
  f.security.add_flags(app);
  app.add_option("--admin", f.admins,
                 "A client identity that may watch, cancel and acknowledge every client's jobs "
                 "(token:NAME of a named client token, cn:NAME of a TLS client certificate); repeatable")
      ->group("Security");
  f.limits.add_flags(app);
  app.set_version_flag("--version", "tessera-server 0.1.0");
  return farm::parse_command_line(app, argc, argv);
}

// Every connection costs a descriptor, and gRPC 1.51 (Debian bookworm) stops accepting for good
// when accept4() fails with EMFILE: the listener is dropped, connections queue and are never
// served again. The usual soft limit (1024) is reached by a thousand idle connections; the hard
// limit is far higher. So take all of it, at start, and say what it is.
// (At the hard limit, accept_guard.h keeps the listener alive.)
void raise_descriptor_limit() {
  rlimit lim{};
  if (getrlimit(RLIMIT_NOFILE, &lim) != 0) return;
  const rlim_t before = lim.rlim_cur;
  if (lim.rlim_cur < lim.rlim_max) {
    lim.rlim_cur = lim.rlim_max;
    if (setrlimit(RLIMIT_NOFILE, &lim) != 0) lim.rlim_cur = before;
  }
  spdlog::info("descriptor limit {} (was {}; hard limit {})", lim.rlim_cur, before, lim.rlim_max);
}


CoordinatorOptions coordinator_options(const ServerFlags& f) {
  CoordinatorOptions opts;
  opts.heartbeat_interval = std::chrono::milliseconds(f.heartbeat_ms);
  opts.scheduler.lease_timeout = std::chrono::milliseconds(f.lease_timeout_ms);
  opts.scheduler.speculate = !f.no_speculation;
  opts.scheduler.max_span_tiles = f.max_span_tiles;
  opts.scheduler.span_seconds = f.span_ms / 1000.0;
  opts.scheduler.stall_timeout = std::chrono::milliseconds(f.stall_timeout_ms);
  opts.scheduler.max_faults = f.max_faults;
  opts.retention = std::chrono::seconds(int64_t(f.retention_hours * 3600));
  opts.max_undelivered_bytes = uint64_t(f.max_undelivered_gb * 1e9);
  opts.delivery_lease = std::chrono::seconds(f.delivery_lease_s);
  opts.watch_backlog_tiles = f.watch_backlog_tiles;
  opts.max_message_bytes = f.limits.max_message_bytes;
  opts.max_resident_tiles = f.limits.max_resident_tiles;
  opts.max_job_tiles = f.limits.max_job_tiles;
  opts.scheduler.max_resident_tiles = f.limits.max_resident_tiles;
  opts.scheduler.max_job_tiles = f.limits.max_job_tiles;
  return opts;
}

// The HTTP side: the web monitor, its JSON API and the Prometheus metrics. Nothing of it exists,
// and nothing observes the farm, unless --http-listen asks for it.
//
// Lifetimes: every part stops before what it uses. The listener's handlers use the feed and the
// metrics, so it stops first, whatever the order of the members. The feed and the metrics
// observe the coordinator (they leave it when destroyed) and the metrics the job store's batches
// (cleared here before the metrics go); both outlive this side (made before it in serve()). The
// job store writes its last batch after the metrics are gone and reports it to no one.
struct HttpSide {
  JobStore* jobs = nullptr;  // whose batch observer is the metrics
  std::unique_ptr<FarmMetrics> metrics;
  std::unique_ptr<MonitorFeed> feed;
  std::unique_ptr<HttpListener> http;
  HttpSide() = default;
  HttpSide(const HttpSide&) = delete;
  HttpSide& operator=(const HttpSide&) = delete;
  ~HttpSide() {
    if (http) http->stop();
    if (jobs) jobs->set_batch_observer({});  // returns once no call to the metrics is in progress
  }
};

// False (said on stderr) when the listener cannot be made: a malformed address, unreadable TLS files.
bool open_http_side(const ServerFlags& f, Coordinator& coordinator, JobStore* jobs, const farm::Authenticator& auth,
                    HttpSide* out) {
  if (f.http_listen.empty()) return true;
  try {
    out->http = std::make_unique<HttpListener>(f.http_listen,
                                               HttpTls{f.security.tls_cert, f.security.tls_key, f.security.tls_ca});
  } catch (const std::exception& e) {
    std::cerr << "tessera-server: " << e.what() << "\n";
    return false;
  }
  out->metrics = std::make_unique<FarmMetrics>(coordinator);
  if (jobs) {
    out->jobs = jobs;
    jobs->set_batch_observer([m = out->metrics.get()](double s, uint64_t bytes) { m->store_batch(s, bytes); });
  }
  out->feed = std::make_unique<MonitorFeed>(coordinator);
  MonitorRoutes{coordinator, *out->feed, out->metrics.get(), auth, {f.admins.begin(), f.admins.end()}}.install(
      *out->http);
  return true;
}

// Builds and starts the gRPC server with both services; null when it cannot listen. `*port` is the
// port bound.
std::unique_ptr<grpc::Server> start_grpc_server(const ServerFlags& f,
                                                const std::shared_ptr<grpc::ServerCredentials>& credentials,
                                                ClientServiceImpl& client_service, WorkerServiceImpl& worker_service,
                                                int* port) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(f.listen, credentials, port);
  builder.RegisterService(&client_service);
  builder.RegisterService(&worker_service);
  builder.SetMaxReceiveMessageSize(int(f.limits.max_message_bytes));  // a 256x256 tile is 1 MiB; bundles: 1 MiB chunks
  farm::set_server_connection_args(builder);  // keepalive pings accepted, 10 s handshakes
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || *port == 0) return nullptr;
  // Probes may ask about each service by name, not only the whole server ("").
  if (auto* health = server->GetHealthCheckService()) {
    for (const char* name : {"tessera.v1.ClientService", "tessera.v1.WorkerService"}) {
      health->SetServingStatus(name, true);
    }
  }
  return server;
}

// The lines on stdout that tests and scripts wait for, and warnings about an exposed monitor.
void print_listening(const ServerFlags& f, int port, const HttpListener* http, int http_port,
                     const farm::Authenticator& auth) {
  const std::string host = f.listen.substr(0, f.listen.rfind(':'));
  std::printf("listening on %s:%d\n", host.c_str(), port);
  if (http) {
    const std::string http_host = f.http_listen.substr(0, f.http_listen.rfind(':'));
    // After the gRPC line: scripts that wait for "listening on" get the gRPC port.
    std::printf("monitor on %s://%s:%d/\n", http->tls() ? "https" : "http", http_host.c_str(), http_port);
    const bool loopback = http_host == "127.0.0.1" || http_host == "localhost" || http_host == "[::1]";
    if (!loopback && auth.open(farm::PeerRole::kClient)) {
      spdlog::warn("the monitor on {} has no client token: anyone who reaches it can see and cancel jobs",
                   f.http_listen);
    } else if (!loopback && !http->tls()) {
      spdlog::warn("the monitor on {} checks client tokens over plain HTTP: tokens cross the network in "
                   "clear; use TLS (--tls-cert) or a reverse proxy with TLS", f.http_listen);
    }
  }
  std::fflush(stdout);
}

// Waits for SIGINT or SIGTERM, then stops taking work and closes the streams.
void serve_until_signal(sigset_t sigs, HttpListener* http, Coordinator& coordinator, grpc::Server& server) {
  spdlog::info("signal {}: shutting down", farm::wait_for_signal(sigs));
  if (http) http->stop();
  coordinator.stop();
  // Give streams a moment to finish; then everything still open is cancelled.
  server.Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  server.Wait();
}

// Runs the coordinator until SIGINT or SIGTERM; returns the exit code. Every component lives in
// this scope and is made after what it uses, so it is destroyed before them: the gRPC server
// first, the job store (which writes everything still queued) and the bundle store last.
int serve(const ServerFlags& flags, const farm::Authenticator& auth,
          const std::shared_ptr<grpc::ServerCredentials>& credentials, const sigset_t& sigs) {
  std::unique_ptr<BundleStore> store;
  std::unique_ptr<JobStore> jobs;
  try {
    store = std::make_unique<BundleStore>(flags.data_dir);
    // The database is the source of truth: a corrupt or unwritable store stops us here, loudly.
    jobs = std::make_unique<JobStore>(flags.data_dir, std::chrono::milliseconds(flags.commit_window_ms));
  } catch (const std::exception& e) {
    std::cerr << "tessera-server: " << e.what() << "\n";
    return 1;
  }
  Coordinator coordinator(coordinator_options(flags), *store, jobs.get());
  HttpSide web;
  if (!open_http_side(flags, coordinator, jobs.get(), auth, &web)) return 2;
  ClientServiceImpl client_service(coordinator, auth, flags.limits, {flags.admins.begin(), flags.admins.end()});
  WorkerServiceImpl worker_service(coordinator, auth);

  int port = 0;
  std::unique_ptr<grpc::Server> server = start_grpc_server(flags, credentials, client_service, worker_service, &port);
  if (!server) {
    std::cerr << "tessera-server: cannot listen on " << flags.listen << " (address in use or not local?)\n";
    return 1;
  }
  spdlog::info("tessera-server 0.1.0: data in {}, heartbeat {} ms, lease timeout {} ms", flags.data_dir,
               flags.heartbeat_ms, flags.lease_timeout_ms);
  flags.security.log_posture(flags.listen, auth);
  int http_port = 0;
  if (web.http) {
    try {
      http_port = web.http->start();
    } catch (const std::exception& e) {
      std::cerr << "tessera-server: " << e.what() << "\n";
      coordinator.stop();
      server->Shutdown();
      return 1;
    }
  }
  print_listening(flags, port, web.http.get(), http_port, auth);

  serve_until_signal(sigs, web.http.get(), coordinator, *server);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const sigset_t sigs = farm::block_stop_signals();  // first: gRPC's threads start with the credentials
  ServerFlags flags;
  if (std::optional<int> exit_code = parse_flags(argc, argv, flags)) return *exit_code;
  farm::Authenticator auth;
  std::shared_ptr<grpc::ServerCredentials> credentials;
  try {
    auth = flags.security.authenticator();
    credentials = flags.security.credentials();
  } catch (const std::exception& e) {
    std::cerr << "tessera-server: " << e.what() << "\n";
    return 2;
  }

  spdlog::set_level(spdlog::level::from_str(flags.log_level));
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  raise_descriptor_limit();
  farm::install_accept_guard();

  const int code = serve(flags, auth, credentials, sigs);
  if (code == 0) spdlog::info("stopped");  // everything is destroyed, the job store's last batch written
  return code;
}

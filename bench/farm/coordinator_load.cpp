// SPDX-License-Identifier: Apache-2.0
// coordinator_load: the coordinator at scale, simulated. For each worker count N it starts a
// fresh tessera-server, connects N simulated workers (sim_worker.h: the real worker protocol,
// a constant tile after a fixed delay), queues one job of M small tiles through the client
// service, lets the workers loose, and receives every tile on a WatchJob stream, acknowledging
// frames as `tessera submit` does. It reports sustained tiles/s, the coordinator's CPU time per
// tile (lease bookkeeping and forwarding), its memory per connected worker and per queued tile
// (VmRSS deltas from /proc), and checks that no tile was lost or delivered twice.
//
// A benchmark, not a test: it asserts nothing about time. It exits 1 if a tile was lost or
// duplicated, or a job did not finish, because that is a bug whatever the machine.
#include <grpcpp/grpcpp.h>
#include <sys/resource.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "farm/bundle.h"
#include "farm/channel.h"
#include "server_process.h"
#include "sim_worker.h"
#include "tessera/v1/client_service.grpc.pb.h"

namespace v1 = tessera::v1;
namespace fs = std::filesystem;
using tessera::bench::ProcStat;
using tessera::bench::ServerProcess;
using tessera::bench::SimCounters;
using tessera::bench::SimOptions;
using tessera::bench::SimTimer;
using tessera::bench::SimWorker;
using tessera::bench::SteadyClock;
using json = nlohmann::json;

namespace {

struct Config {
  fs::path server;
  fs::path scene;
  std::vector<int> workers{10, 100, 1000};
  int64_t tiles = 50000;
  int tile = 8;
  int delay_us = 0;
  int threads = 1;
  int connections = 0;  // 0: one TCP connection per worker, as real workers have
  bool no_batches = false;  // the protocol before batches: one result and one assignment a message
  bool no_spans = false;    // the protocol before spans: a lease is one tile
  int linger_ms = int(tessera::farm::ResultBatching{}.linger.count());
  int timeout_s = 300;
  std::string log_level = "info";
  std::vector<std::string> server_args;
  fs::path work_dir;
  fs::path profile_dir;  // perf record the coordinator during each run, if set
  std::vector<int> server_cpus;   // the coordinator's CPUs (empty: any)
};

// `perf record -g -p PID` until stopped: where the coordinator's CPU goes during a run.
class Profiler {
 public:
  Profiler(pid_t target, const fs::path& out) {
    pid_ = fork();
    if (pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      const std::string p = std::to_string(target), o = out.string();
      execlp("perf", "perf", "record", "-q", "-F", "999", "-g", "-p", p.c_str(), "-o", o.c_str(), (char*)nullptr);
      _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // perf attaches
  }
  ~Profiler() {
    if (pid_ <= 0) return;
    kill(pid_, SIGINT);
    int status = 0;
    waitpid(pid_, &status, 0);
  }

 private:
  pid_t pid_ = -1;
};

double now_s() { return std::chrono::duration<double>(SteadyClock::now().time_since_epoch()).count(); }

double self_cpu_seconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e6;
}

// Each simulated worker gets its own TCP connection unless --connections says otherwise: gRPC
// shares one connection between channels with equal arguments, so a distinct argument per
// channel (and a local subchannel pool) forces separate ones. Otherwise the same arguments as
// farm::make_coordinator_channel (keepalive, message size).
std::shared_ptr<grpc::Channel> sim_channel(const std::string& address, int index) {
  grpc::ChannelArguments args = tessera::farm::coordinator_channel_args();
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetInt("tessera.bench.connection", index);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

template <class T>
T wait_for(std::chrono::seconds timeout, const std::function<std::optional<T>()>& poll) {
  const auto deadline = SteadyClock::now() + timeout;
  for (;;) {
    if (auto v = poll()) return *v;
    if (SteadyClock::now() > deadline) throw std::runtime_error("timed out");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

void check(const grpc::Status& s, const std::string& what) {
  if (!s.ok()) throw std::runtime_error(what + ": " + s.error_message());
}

std::unique_ptr<grpc::ClientContext> call_ctx(int seconds = 30) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(seconds));
  return ctx;
}

std::string upload_bundle(v1::ClientService::Stub& stub, const fs::path& scene) {
  const auto b = tessera::farm::make_bundle(scene, {});
  auto ctx = call_ctx();
  v1::UploadBundleResponse resp;
  auto writer = stub.UploadBundle(ctx.get(), &resp);
  v1::BundleChunk chunk;
  chunk.set_sha256(b.sha256);
  chunk.set_data(b.bytes);
  writer->Write(chunk);
  writer->WritesDone();
  check(writer->Finish(), "UploadBundle");
  return b.sha256;
}

// Receives the job's tiles as `tessera submit` does and checks that each arrives exactly once.
class Watcher {
 public:
  Watcher(v1::ClientService::Stub& stub, const v1::JobStatus& job)
      : stub_(stub),
        job_(job),
        seen_(size_t(job.tiles_total()), 0),
        frame_done_(size_t(job.last_frame() - job.first_frame() + 1), 0) {
    thread_ = std::thread([this] { run(); });
  }
  ~Watcher() { stop(); }
  // Ends the stream (if still open) and joins the reader: its counters are then safe to read.
  void stop() {
    ctx_.TryCancel();
    if (thread_.joinable()) thread_.join();
  }
  // Blocks until the final status arrives or the timeout passes. True if the job ended.
  bool wait(std::chrono::seconds timeout) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [this] { return ended_; });
  }
  int64_t received() const { return received_.load(); }

  int64_t duplicates = 0, out_of_range = 0, acks_failed = 0;
  int64_t tile_messages = 0;  // watch events that carried tiles (one, or a batch)
  double t_first = 0, t_10 = 0, t_90 = 0, t_last = 0;
  v1::JobStatus final_status;
  grpc::Status stream_status;

  int64_t missing() const {
    int64_t n = 0;
    for (char c : seen_) n += c == 0;
    return n;
  }
  int64_t frames_without_done() const {
    int64_t n = 0;
    for (char c : frame_done_) n += c == 0;
    return n;
  }

 private:
  void count_tile(const v1::TileData& t) {
    const int64_t total = job_.tiles_total();
    const int tpf = job_.tiles_per_frame();
    const int64_t idx = int64_t(t.frame() - job_.first_frame()) * tpf + t.tile_index();
    if (idx < 0 || idx >= total || t.tile_index() >= tpf) {
      ++out_of_range;
      return;
    }
    if (seen_[size_t(idx)]++) {
      ++duplicates;
      return;
    }
    const int64_t n = ++received_;
    const double t_now = now_s();
    if (n == 1) t_first = t_now;
    if (n == std::max<int64_t>(1, total / 10)) t_10 = t_now;
    if (n == std::max<int64_t>(1, total * 9 / 10)) t_90 = t_now;
    t_last = t_now;
  }

  void run() {
    v1::WatchJobRequest req;
    req.set_job_id(job_.job_id());
    req.set_tile_batches(true);  // as tessera watch does
    auto reader = stub_.WatchJob(&ctx_, req);
    v1::WatchJobEvent ev;
    v1::TileData batched;
    while (reader->Read(&ev)) {
      if (ev.has_tile()) {
        ++tile_messages;
        count_tile(ev.tile());
      } else if (ev.has_tiles()) {
        ++tile_messages;
        for (const std::string& bytes : ev.tiles().tiles()) {
          if (batched.ParseFromString(bytes)) {
            count_tile(batched);
          } else {
            ++out_of_range;
          }
        }
      } else if (ev.event_case() == v1::WatchJobEvent::kFrameDone) {
        const int f = ev.frame_done() - job_.first_frame();
        if (f >= 0 && size_t(f) < frame_done_.size()) frame_done_[size_t(f)] = 1;
        // Like the CLI after writing the EXR: the coordinator may release the frame's tiles.
        v1::AckFrameRequest ack;
        ack.set_job_id(job_.job_id());
        ack.set_frame(ev.frame_done());
        v1::AckFrameResponse r;
        auto ctx = call_ctx(15);
        if (!stub_.AckFrame(ctx.get(), ack, &r).ok()) ++acks_failed;
      } else if (ev.has_status()) {
        final_status = ev.status();
      }
    }
    stream_status = reader->Finish();
    std::lock_guard lock(mu_);
    ended_ = true;
    cv_.notify_all();
  }

  v1::ClientService::Stub& stub_;
  v1::JobStatus job_;
  grpc::ClientContext ctx_;
  std::vector<char> seen_;
  std::vector<char> frame_done_;
  std::atomic<int64_t> received_{0};
  std::mutex mu_;
  std::condition_variable cv_;
  bool ended_ = false;
  std::thread thread_;
};

// The simulated workers, their connections and their timer. stop() (also from the destructor,
// e.g. when a run throws) ends every session before anything is destroyed.
struct SimFleet {
  SimFleet(const std::string& address, int n_workers, int n_conn, SimOptions options) {
    for (int i = 0; i < n_conn; ++i) {
      channels.push_back(sim_channel(address, i));
      stubs.push_back(v1::WorkerService::NewStub(channels.back()));
    }
    for (int i = 0; i < n_workers; ++i) {
      workers.push_back(std::make_unique<SimWorker>(stubs[size_t(i % n_conn)].get(), "sim" + std::to_string(i),
                                                    options, timer, counters));
      workers.back()->start();
    }
  }
  ~SimFleet() { stop(); }
  void stop() {
    for (auto& w : workers) w->stop();
    const auto deadline = SteadyClock::now() + std::chrono::seconds(20);
    for (auto& w : workers) w->wait_done(deadline);
    timer.stop();
    workers.clear();
  }
  SimTimer timer;
  SimCounters counters;
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  std::vector<std::unique_ptr<v1::WorkerService::Stub>> stubs;
  std::vector<std::unique_ptr<SimWorker>> workers;
};

json run_one(const Config& cfg, int n_workers, int run_index) {
  const fs::path dir = cfg.work_dir / ("n" + std::to_string(n_workers) + "_" + std::to_string(run_index));
  std::vector<std::string> extra = {"--log-level", cfg.log_level};
  extra.insert(extra.end(), cfg.server_args.begin(), cfg.server_args.end());
  ServerProcess server(cfg.server, dir, extra, cfg.server_cpus);
  auto client_channel = tessera::farm::make_coordinator_channel(server.address());
  auto client = v1::ClientService::NewStub(client_channel);

  // Idle: the server up, one client connection, nothing else.
  {
    auto ctx = call_ctx();
    v1::ListJobsRequest req;
    v1::ListJobsResponse resp;
    check(client->ListJobs(ctx.get(), req, &resp), "ListJobs");
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const ProcStat idle = server.stat();

  // N workers connected and registered, nothing requested yet.
  SimOptions sim;
  sim.threads = cfg.threads;
  sim.delay = std::chrono::microseconds(cfg.delay_us);
  sim.batches = !cfg.no_batches;
  sim.spans = !cfg.no_spans;
  sim.batching.linger = std::chrono::milliseconds(cfg.linger_ms);
  const int n_conn = cfg.connections > 0 ? std::min(cfg.connections, n_workers) : n_workers;
  const double t_connect0 = now_s();
  SimFleet fleet(server.address(), n_workers, n_conn, sim);
  auto& workers = fleet.workers;
  auto& counters = fleet.counters;
  wait_for<bool>(std::chrono::seconds(60), [&]() -> std::optional<bool> {
    for (auto& w : workers)
      if (!w->welcomed()) return std::nullopt;
    return true;
  });
  const double connect_s = now_s() - t_connect0;
  {
    auto ctx = call_ctx();
    v1::ListWorkersRequest req;
    v1::ListWorkersResponse resp;
    check(client->ListWorkers(ctx.get(), req, &resp), "ListWorkers");
    if (resp.workers_size() != n_workers) {
      throw std::runtime_error("coordinator lists " + std::to_string(resp.workers_size()) + " workers, expected " +
                               std::to_string(n_workers));
    }
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const ProcStat connected = server.stat();

  // One job of M tiles queued (tiles_x x tiles_x tiles per frame, as many frames as needed).
  const std::string sha = upload_bundle(*client, cfg.scene);
  const int tiles_x = 8;
  const int tpf = tiles_x * tiles_x;
  const int64_t frames = std::max<int64_t>(1, (cfg.tiles + tpf - 1) / tpf);
  if (frames > 100000) throw std::runtime_error("--tiles: at most 6400000 (100000 frames of 64 tiles)");
  v1::SubmitJobRequest sreq;
  sreq.set_bundle_sha256(sha);
  sreq.mutable_overrides()->set_width(cfg.tile * tiles_x);
  sreq.mutable_overrides()->set_height(cfg.tile * tiles_x);
  sreq.mutable_overrides()->set_spp(1);
  sreq.set_first_frame(0);
  sreq.set_last_frame(int(frames - 1));
  sreq.set_tile_size(cfg.tile);
  sreq.set_name("coordinator_load");
  v1::JobStatus job;
  {
    auto ctx = call_ctx();
    check(client->SubmitJob(ctx.get(), sreq, &job), "SubmitJob");
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const ProcStat queued = server.stat();

  // Let them loose; the watcher receives every tile and acknowledges every frame.
  Watcher watcher(*client, job);
  std::unique_ptr<Profiler> profiler;
  if (!cfg.profile_dir.empty()) {
    fs::create_directories(cfg.profile_dir);
    profiler = std::make_unique<Profiler>(server.pid(), cfg.profile_dir / ("coordinator-" + std::to_string(n_workers) +
                                                                           "-" + std::to_string(run_index) + ".perf"));
  }
  // The coordinator's own count, sampled: when did it have every tile (the watcher may lag)?
  std::atomic<bool> sampling{true};
  double coordinator_all_done = 0;
  std::thread sampler([&] {
    while (sampling) {
      v1::GetJobRequest req;
      req.set_job_id(job.job_id());
      v1::JobStatus st;
      auto ctx = call_ctx(5);
      if (client->GetJob(ctx.get(), req, &st).ok() && st.tiles_done() >= st.tiles_total()) {
        coordinator_all_done = now_s();
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  const double cpu_self0 = self_cpu_seconds();
  const ProcStat before = server.stat();
  const double t0 = now_s();
  for (auto& w : workers) w->go();
  const bool ended = watcher.wait(std::chrono::seconds(cfg.timeout_s));
  const double t1 = now_s();
  const ProcStat after = server.stat();
  const double cpu_self = self_cpu_seconds() - cpu_self0;
  watcher.stop();
  sampling = false;
  sampler.join();
  profiler.reset();

  v1::JobStatus final_job;
  {
    auto ctx = call_ctx();
    v1::GetJobRequest req;
    req.set_job_id(job.job_id());
    check(client->GetJob(ctx.get(), req, &final_job), "GetJob");
  }
  int64_t ended_early = 0;
  for (auto& w : workers) ended_early += w->ended_early();
  fleet.stop();
  const ProcStat end = server.stat();
  server.stop();

  const int64_t total = job.tiles_total();
  const int64_t received = watcher.received();
  const double wall = (watcher.t_last > 0 ? watcher.t_last : t1) - t0;
  const double server_cpu = after.cpu_seconds - before.cpu_seconds;
  const bool complete = ended && final_job.state() == v1::JOB_STATE_DONE && final_job.tiles_done() == total &&
                        int64_t(final_job.frames_done_size()) == frames && watcher.missing() == 0 &&
                        watcher.duplicates == 0 && watcher.out_of_range == 0 && watcher.frames_without_done() == 0;
  json r;
  r["workers"] = n_workers;
  r["connections"] = n_conn;
  r["tile_px"] = cfg.tile;
  r["delay_us"] = cfg.delay_us;
  r["tiles"] = total;
  r["frames"] = frames;
  r["complete"] = complete;
  r["tiles_received"] = received;
  r["tiles_missing"] = watcher.missing();
  r["tiles_delivered_twice"] = watcher.duplicates;
  r["watch_tiles_per_message"] = watcher.tile_messages > 0 ? double(received) / double(watcher.tile_messages) : 0.0;
  r["frames_without_frame_done"] = watcher.frames_without_done();
  r["ack_failures"] = watcher.acks_failed;
  r["job_state"] = v1::JobState_Name(final_job.state());
  r["coordinator_tiles_rendered_twice"] = final_job.tiles_rendered_twice();
  r["workers_dropped_by_coordinator"] = ended_early;
  r["seconds"] = wall;
  r["tiles_per_second"] = wall > 0 ? double(received) / wall : 0.0;
  r["tiles_per_second_10_90"] =
      watcher.t_90 > watcher.t_10 ? double(total * 9 / 10 - total / 10) / (watcher.t_90 - watcher.t_10) : 0.0;
  r["seconds_to_10pct"] = watcher.t_10 > 0 ? watcher.t_10 - t0 : -1.0;
  r["seconds_after_90pct"] = watcher.t_90 > 0 ? watcher.t_last - watcher.t_90 : -1.0;
  r["coordinator_all_done_s"] = coordinator_all_done > 0 ? coordinator_all_done - t0 : -1.0;
  r["first_tile_ms"] = watcher.t_first > 0 ? (watcher.t_first - t0) * 1e3 : -1.0;
  r["connect_seconds"] = connect_s;
  r["coordinator_cpu_seconds"] = server_cpu;
  r["coordinator_cpu_us_per_tile"] = received > 0 ? server_cpu / double(received) * 1e6 : 0.0;
  r["coordinator_cpu_utilisation"] = wall > 0 ? server_cpu / wall : 0.0;
  r["loadgen_cpu_seconds"] = cpu_self;
  r["coordinator_threads"] = after.threads;
  r["rss_idle_kib"] = idle.rss_kb;
  r["rss_connected_kib"] = connected.rss_kb;
  r["rss_queued_kib"] = queued.rss_kb;
  r["rss_after_run_kib"] = after.rss_kb;
  r["rss_after_disconnect_kib"] = end.rss_kb;
  r["hwm_kib"] = end.hwm_kb;
  r["kib_per_worker"] = double(connected.rss_kb - idle.rss_kb) / n_workers;
  r["bytes_per_queued_tile"] = double(queued.rss_kb - connected.rss_kb) * 1024.0 / double(total);
  r["sim_assignments"] = counters.assignments.load();
  r["sim_assigned_tiles"] = counters.assigned_tiles.load();
  r["sim_refused_spans"] = counters.refused.load();
  r["sim_results"] = counters.results.load();
  r["sim_result_messages"] = counters.result_messages.load();
  r["results_per_message"] = counters.result_messages.load() > 0
                                 ? double(counters.results.load()) / double(counters.result_messages.load())
                                 : 0.0;
  r["batches"] = !cfg.no_batches;
  r["spans"] = !cfg.no_spans;
  r["sim_revoked_while_pending"] = counters.revoked.load();
  r["sim_heartbeats"] = counters.heartbeats.load();
  r["worker_wire_bytes_per_tile"] =
      received > 0 ? double(counters.bytes_out.load() + counters.bytes_in.load()) / double(received) : 0.0;
  if (!watcher.stream_status.ok()) r["watch_status"] = watcher.stream_status.error_message();
  return r;
}

std::string fmt(double v, int prec) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

std::string markdown(const json& runs) {
  std::ostringstream o;
  o << "| workers | tiles | complete | tiles/s | tiles/s (10-90%) | first tile ms | coord. CPU µs/tile | coord. CPU "
       "use | loadgen CPU s | RSS idle MiB | KiB/worker | B/queued tile | peak RSS MiB |\n";
  o << "|---:|---:|:---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& r : runs) {
    o << "| " << r["workers"].get<int>() << " | " << r["tiles"].get<int64_t>() << " | "
      << (r["complete"].get<bool>() ? "yes" : "**NO**") << " | " << fmt(r["tiles_per_second"], 0) << " | "
      << fmt(r["tiles_per_second_10_90"], 0) << " | " << fmt(r["first_tile_ms"], 1) << " | "
      << fmt(r["coordinator_cpu_us_per_tile"], 1) << " | " << fmt(r["coordinator_cpu_utilisation"], 2) << " | "
      << fmt(r["loadgen_cpu_seconds"], 1) << " | " << fmt(r["rss_idle_kib"].get<double>() / 1024, 1) << " | "
      << fmt(r["kib_per_worker"], 1) << " | " << fmt(r["bytes_per_queued_tile"], 0) << " | "
      << fmt(r["hwm_kib"].get<double>() / 1024, 1) << " |\n";
  }
  return o.str();
}

}  // namespace

int main(int argc, char** argv) {
  Config cfg;
  std::string json_out, md_out;
  int repeat = 1;
  CLI::App app{"coordinator_load: a real tessera-server against hundreds of simulated workers"};
  app.add_option("--server", cfg.server, "tessera-server binary")->required()->check(CLI::ExistingFile);
  app.add_option("--scene", cfg.scene, "Scene with enough frames (bench/farm/load_scene.json)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--workers", cfg.workers, "Simulated worker counts, one run each")->delimiter(',')->capture_default_str();
  app.add_option("--tiles", cfg.tiles, "Tiles in each run's job (rounded up to whole frames of 64)")
      ->check(CLI::Range(int64_t(1), int64_t(6400000)))
      ->capture_default_str();
  app.add_option("--tile", cfg.tile, "Tile size in pixels")->check(CLI::Range(4, 256))->capture_default_str();
  app.add_option("--delay-us", cfg.delay_us, "Simulated render time of a tile")
      ->check(CLI::Range(0, 60000000))
      ->capture_default_str();
  app.add_option("--threads", cfg.threads, "Threads each simulated worker reports (its pull depth follows)")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--connections", cfg.connections, "TCP connections shared by the workers (0: one each)")
      ->capture_default_str();
  app.add_flag("--no-batches", cfg.no_batches,
               "Workers as before batches: one result and one assignment a message, 2 x threads tiles pulled");
  app.add_flag("--no-spans", cfg.no_spans, "Workers as before span leases: every lease one tile");
  app.add_option("--linger-ms", cfg.linger_ms, "How long a simulated worker's result waits for others")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--timeout-s", cfg.timeout_s, "Give up on a run after this long")->capture_default_str();
  app.add_option("--log-level", cfg.log_level, "The coordinator's --log-level")->capture_default_str();
  app.add_option("--server-arg", cfg.server_args, "Extra tessera-server argument (repeatable)");
  app.add_option("--repeat", repeat, "Runs per worker count")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_option("--json", json_out, "Write the JSON results here (default: stdout, after the table)");
  app.add_option("--markdown", md_out, "Write the markdown table here too");
  app.add_option("--profile", cfg.profile_dir, "perf record the coordinator during each run into this directory");
  std::string server_cpus, loadgen_cpus;
  app.add_option("--server-cpus", server_cpus, "Run the coordinator on these CPUs only, e.g. 0-3 (default: any)");
  app.add_option("--loadgen-cpus", loadgen_cpus, "Run the simulated workers on these CPUs only (default: any)");
  CLI11_PARSE(app, argc, argv);
  try {
    if (!server_cpus.empty()) cfg.server_cpus = tessera::bench::parse_cpu_list(server_cpus);
    tessera::bench::pin_to_cpus(loadgen_cpus.empty() ? std::vector<int>{} : tessera::bench::parse_cpu_list(loadgen_cpus));
  } catch (const std::exception& e) {
    std::cerr << "coordinator_load: --server-cpus/--loadgen-cpus: " << e.what() << "\n";
    return 2;
  }

  char tmpl[] = "/tmp/tessera-coordinator-load-XXXXXX";
  if (!mkdtemp(tmpl)) {
    std::cerr << "coordinator_load: cannot create a temporary directory\n";
    return 1;
  }
  cfg.work_dir = tmpl;
  json runs = json::array();
  bool ok = true;
  for (int n : cfg.workers) {
    if (n < 1) {
      std::cerr << "coordinator_load: --workers: counts must be >= 1, got " << n << "\n";
      return 2;
    }
    for (int k = 0; k < repeat; ++k) {
      std::cerr << "coordinator_load: " << n << " workers, " << cfg.tiles << " tiles ...\n";
      try {
        json r = run_one(cfg, n, k);
        std::cerr << "  " << fmt(r["tiles_per_second"], 0) << " tiles/s, coordinator "
                  << fmt(r["coordinator_cpu_us_per_tile"], 1) << " µs CPU/tile, complete: " << r["complete"] << "\n";
        ok = ok && r["complete"].get<bool>();
        runs.push_back(std::move(r));
      } catch (const std::exception& e) {
        std::cerr << "coordinator_load: run with " << n << " workers failed: " << e.what() << " (logs in "
                  << cfg.work_dir << ")\n";
        return 1;
      }
    }
  }
  json out;
  out["benchmark"] = "coordinator_load";
  out["cores"] = std::thread::hardware_concurrency();
  out["server_cpus"] = cfg.server_cpus;
  out["loadgen_cpus"] = loadgen_cpus;
  out["runs"] = runs;
  const std::string table = markdown(runs);
  std::cout << table << std::flush;
  if (!md_out.empty()) std::ofstream(md_out) << table;
  if (json_out.empty()) {
    std::cout << "\n" << out.dump(2) << "\n";
  } else {
    std::ofstream(json_out) << out.dump(2) << "\n";
  }
  if (ok) fs::remove_all(cfg.work_dir);
  else std::cerr << "coordinator_load: tiles were lost or duplicated (logs in " << cfg.work_dir << ")\n";
  return ok ? 0 : 1;
}

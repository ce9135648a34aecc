// SPDX-License-Identifier: Apache-2.0
// first_tile_probe: the time from submit to first tile, seen from outside the coordinator.
// Started before `tessera submit`, it polls ListJobs until a job appears, attaches a WatchJob
// stream to it and prints, as JSON, the coordinator's submit time of the job and the time the
// first finished tile reached this probe (both Unix seconds, same machine clock). It never
// acknowledges a frame, so the real client receives every tile as usual.
//
// `exact` is false if the job already had finished tiles when the probe attached (the first
// tile then arrived before the probe could see it; first_tile_unix is an upper bound).
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <thread>

#include "farm/channel.h"
#include "tessera/v1/client_service.grpc.pb.h"

namespace v1 = tessera::v1;

namespace {
double unix_now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}
}  // namespace

int main(int argc, char** argv) {
  std::string address;
  double timeout_s = 600;
  int poll_ms = 2;
  CLI::App app{"first_tile_probe: when did the first tile of the next job arrive?"};
  app.add_option("--coordinator", address, "HOST:PORT of tessera-server")->required();
  app.add_option("--timeout-s", timeout_s, "Give up after this long")->capture_default_str();
  app.add_option("--poll-ms", poll_ms, "ListJobs polling interval")->check(CLI::Range(1, 1000))->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  auto stub = v1::ClientService::NewStub(tessera::farm::make_coordinator_channel(address));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  std::string job;
  while (job.empty()) {
    if (std::chrono::steady_clock::now() > deadline) {
      std::fprintf(stderr, "first_tile_probe: no job appeared on %s\n", address.c_str());
      return 1;
    }
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    v1::ListJobsResponse resp;
    if (stub->ListJobs(&ctx, v1::ListJobsRequest{}, &resp).ok() && resp.jobs_size() > 0) {
      job = resp.jobs(0).job_id();
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(poll_ms));
  }
  const double attach = unix_now();
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(int64_t(timeout_s * 1000)));
  v1::WatchJobRequest req;
  req.set_job_id(job);
  auto reader = stub->WatchJob(&ctx, req);
  v1::WatchJobEvent ev;
  double submitted = 0, first = 0;
  int64_t done_at_attach = -1;
  while (reader->Read(&ev)) {
    if (ev.has_status() && done_at_attach < 0) {
      submitted = ev.status().submitted_unix();
      done_at_attach = ev.status().tiles_done();
    } else if (ev.has_tile()) {
      first = unix_now();
      break;
    }
  }
  ctx.TryCancel();
  reader->Finish();
  if (first == 0) {
    std::fprintf(stderr, "first_tile_probe: job %s ended without a tile reaching the probe\n", job.c_str());
    return 1;
  }
  nlohmann::json out = {{"job", job},
                        {"submitted_unix", submitted},
                        {"attached_unix", attach},
                        {"first_tile_unix", first},
                        {"exact", done_at_attach == 0}};
  std::printf("%s\n", out.dump().c_str());
  return 0;
}

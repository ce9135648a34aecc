// SPDX-License-Identifier: Apache-2.0
// `tessera status [JOB]`, `tessera cancel JOB`, `tessera priority JOB N`: one call about a job
// (or the list of jobs) on the coordinator, and its answer as a table or JSON.
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.h"
#include "duration_text.h"
#include "farm_command.h"
#include "job_output.h"
#include "job_text.h"

namespace tessera::cli {

namespace v1 = tessera::v1;

namespace {

struct JobArgs {
  std::string coordinator, job;
  SecurityFlags security;
  bool json = false;
  int priority = 0;  // `tessera priority`
  bool discard = false;  // `tessera cancel --discard`
};

nlohmann::json job_json(const v1::JobStatus& j) {
  return {{"job_id", j.job_id()},
          {"name", j.name()},
          {"state", state_name(j.state())},
          {"priority", j.priority()},
          {"bundle_sha256", j.bundle_sha256()},
          {"first_frame", j.first_frame()},
          {"last_frame", j.last_frame()},
          {"width", j.width()},
          {"height", j.height()},
          {"spp", j.spp()},
          {"target_rmse", j.overrides().has_target_rmse() ? nlohmann::json(j.overrides().target_rmse()) : nlohmann::json(nullptr)},
          {"block_rmse", j.overrides().has_block_rmse() ? nlohmann::json(j.overrides().block_rmse()) : nlohmann::json(nullptr)},
          {"tile_size", j.tile_size()},
          {"tiles_total", j.tiles_total()},
          {"tiles_done", j.tiles_done()},
          {"tiles_leased", j.tiles_leased()},
          {"tiles_rendered_twice", j.tiles_rendered_twice()},
          {"rays", j.rays()},
          {"elapsed_seconds", j.elapsed_seconds()},
          {"frames_done", std::vector<int>(j.frames_done().begin(), j.frames_done().end())},
          {"frames_acknowledged",
           std::vector<int>(j.frames_acknowledged().begin(), j.frames_acknowledged().end())},
          {"error", j.error()},
          {"blocklisted_workers",
           std::vector<std::string>(j.blocklisted_workers().begin(), j.blocklisted_workers().end())},
          {"tiles_resident", j.tiles_resident()},
          {"waiting_for_memory", j.waiting_for_memory()},
          {"output", job_output_json(j)},
          {"owner", j.owner()}};
}

void print_job(const v1::JobStatus& j) {
  const std::string frames = std::to_string(j.first_frame()) + "-" + std::to_string(j.last_frame());
  const std::string size = std::to_string(j.width()) + "x" + std::to_string(j.height());
  const std::string tiles = std::to_string(j.tiles_done()) + "/" + std::to_string(j.tiles_total());
  std::printf("%-14s %-10s %5d  %-11s %-11s %6d  %-15s %9s  %s\n", j.job_id().c_str(), state_name(j.state()),
              j.priority(), frames.c_str(), size.c_str(), j.spp(), tiles.c_str(),
              format_duration(j.elapsed_seconds()).c_str(), j.name().c_str());
  if (j.has_output()) std::printf("%-14s output: %s\n", "", j.output().pattern().c_str());
  if (j.waiting_for_memory()) {
    std::printf("%-14s waiting for memory: its next frame would hold more tiles than tessera-server "
                "--max-job-tiles/--max-resident-tiles allow until clients receive finished frames\n", "");
  }
}

// The one job asked for, or every job on the coordinator.
std::vector<v1::JobStatus> fetch_jobs(FarmClient& client, const std::string& job, v1::DeliveryBacklog* backlog) {
  std::vector<v1::JobStatus> jobs;
  if (!job.empty()) {
    jobs.push_back(get_job(client, job));
  } else {
    v1::ListJobsResponse resp;
    auto ctx = client.context();
    grpc::Status s = client.stub().ListJobs(ctx.get(), {}, &resp);
    if (!s.ok()) throw CommandError{kExitFailure, client.describe(s, "listing jobs")};
    jobs.assign(resp.jobs().begin(), resp.jobs().end());
    *backlog = resp.delivery();
  }
  return jobs;
}

int run_status(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::DeliveryBacklog backlog;
  const std::vector<v1::JobStatus> jobs = fetch_jobs(client, a.job, &backlog);
  if (a.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& j : jobs) out.push_back(job_json(j));
    std::cout << (a.job.empty() ? out.dump(2) : out[0].dump(2)) << "\n";
    return 0;
  }
  if (jobs.empty()) {
    std::printf("no jobs on %s\n", client.address().c_str());
    return 0;
  }
  std::printf("%-14s %-10s %5s  %-11s %-11s %6s  %-15s %9s  %s\n", "JOB", "STATE", "PRIO", "FRAMES", "SIZE", "SPP",
              "TILES", "ELAPSED", "NAME");
  for (const auto& j : jobs) print_job(j);
  if (backlog.frames() > 0) {
    char limit[64] = "no limit";
    if (backlog.limit_bytes()) std::snprintf(limit, sizeof limit, "%.3g GB", double(backlog.limit_bytes()) / 1e9);
    std::printf("undelivered: %lld finished frames (%.2f GB) of jobs with a recorded output, the oldest finished %s "
                "ago; kept until `tessera collect` or `tessera watch JOB` writes them (new jobs are refused at %s)\n",
                (long long)backlog.frames(), double(backlog.bytes()) / 1e9,
                format_duration(backlog.oldest_seconds()).c_str(),
                limit);
  }
  return 0;
}

int run_cancel(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::CancelJobRequest req;
  req.set_job_id(a.job);
  req.set_discard_undelivered(a.discard);
  v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().CancelJob(ctx.get(), req, &st);
  if (!s.ok()) {
    throw job_error(client, s, "cancelling job " + a.job);
  }
  std::printf("job %s: %s (%lld/%lld tiles were done)%s\n", st.job_id().c_str(), state_name(st.state()),
              (long long)st.tiles_done(), (long long)st.tiles_total(),
              a.discard ? "; its finished frames not yet delivered are discarded" : "");
  return 0;
}

int run_priority(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::SetJobPriorityRequest req;
  req.set_job_id(a.job);
  req.set_priority(a.priority);
  v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().SetJobPriority(ctx.get(), req, &st);
  if (!s.ok()) throw job_error(client, s, "changing the priority of job " + a.job);
  std::printf("job %s: priority %d (%s, %lld/%lld tiles done)\n", st.job_id().c_str(), st.priority(),
              state_name(st.state()), (long long)st.tiles_done(), (long long)st.tiles_total());
  return 0;
}

}  // namespace

void register_job_commands(CLI::App& app) {
  {
    auto a = std::make_shared<JobArgs>();
    CLI::App* cmd = app.add_subcommand("status", "Show one job, or all jobs");
    cmd->add_option("job", a->job, "Job id (default: all jobs)");
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->add_flag("--json", a->json, "Machine-readable output");
    cmd->callback([a] { guarded("status", [&] { return run_status(*a); }); });
  }
  {
    auto a = std::make_shared<JobArgs>();
    CLI::App* cmd = app.add_subcommand("cancel", "Cancel a job: no more of its tiles are handed out");
    cmd->add_option("job", a->job, "Job id")->required();
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->add_flag("--discard", a->discard,
                  "Also drop its finished frames that no client has delivered (also of a job that ended): they "
                  "are deleted from the coordinator, never written");
    cmd->callback([a] { guarded("cancel", [&] { return run_cancel(*a); }); });
  }
  {
    auto a = std::make_shared<JobArgs>();
    CLI::App* cmd = app.add_subcommand("priority", "Change a queued or running job's priority (higher runs first)");
    cmd->add_option("job", a->job, "Job id")->required();
    cmd->add_option("priority", a->priority, "The new priority")->required();
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->callback([a] { guarded("priority", [&] { return run_priority(*a); }); });
  }
}

}  // namespace tessera::cli

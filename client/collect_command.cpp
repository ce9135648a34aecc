// SPDX-License-Identifier: Apache-2.0
// `tessera collect`: the farm's delivery process. It attaches, as a deliverer, to every job on the
// coordinator that carries a recorded output (`tessera submit -o`), optionally only those under
// some path prefixes or of some owners, writes each frame it is leased where the job says (beside
// its name, renamed into place) and acknowledges it after the write. Several may run at once: the
// coordinator leases each frame to one deliverer at a time (docs/farm.md, "Delivery"). It runs on
// a machine that mounts the studio's storage at the path the patterns name (docker/systemd/,
// docker/k8s/collect/).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "commands.h"
#include "farm_command.h"
#include "interrupt.h"
#include "job_output.h"
#include "job_text.h"
#include "watch_job.h"

namespace tessera::cli {

namespace v1 = tessera::v1;
using Clock = std::chrono::steady_clock;

namespace {

struct CollectArgs {
  std::string coordinator;
  SecurityFlags security;
  std::vector<std::string> under;   // recorded patterns must start with one of these
  std::vector<std::string> owners;  // submitted by one of these identities
  double poll_seconds = 5;
  bool once = false;
};

// Has the job frames to deliver, now or later?
bool undelivered(const v1::JobStatus& j) {
  if (!is_final(j.state())) return true;
  return j.frames_acknowledged_size() < j.frames_done_size();
}

bool wanted(const v1::JobStatus& j, const CollectArgs& a) {
  if (!j.has_output() || j.output().pattern().empty()) return false;
  if (!a.owners.empty() && std::find(a.owners.begin(), a.owners.end(), j.owner()) == a.owners.end()) return false;
  if (a.under.empty()) return true;
  return std::any_of(a.under.begin(), a.under.end(),
                     [&](const std::string& p) { return j.output().pattern().rfind(p, 0) == 0; });
}

// One job's delivery, on its own thread: a watch with the job's recorded output.
struct Delivery {
  std::thread thread;
  std::atomic<bool> finished{false};
  std::string error;  // why it stopped short of delivering the job; empty when it did
  grpc::StatusCode refused = grpc::StatusCode::OK;
};

class Collector {
 public:
  Collector(FarmClient& client, const CollectArgs& a) : client_(client), a_(a) {}
  ~Collector() {
    for (auto& [id, d] : active_) d->thread.join();
  }

  int run() {
    bool first = true;
    while (true) {
      if (poll(first)) first = false;
      reap();
      if (a_.once && !first && active_.empty()) break;
      std::this_thread::sleep_for(std::chrono::duration<double>(a_.poll_seconds));
    }
    std::printf("collect: %d jobs delivered, %d failed\n", delivered_, failed_);
    return failed_ ? kExitFailure : 0;
  }

 private:
  // Starts a delivery for every wanted job without one; false when the coordinator did not answer.
  bool poll(bool first) {
    v1::ListJobsResponse resp;
    auto ctx = client_.context();
    const grpc::Status s = client_.stub().ListJobs(ctx.get(), {}, &resp);
    if (!s.ok()) {
      spdlog::warn("{}; trying again in {} s", client_.describe(s, "listing jobs"), a_.poll_seconds);
      return false;
    }
    for (const v1::JobStatus& j : resp.jobs()) {
      if (active_.count(j.job_id()) || !wanted(j, a_) || !undelivered(j)) continue;
      if (a_.once && !first && !seen_.count(j.job_id())) continue;  // --once: the jobs there at start
      if (auto r = retry_at_.find(j.job_id()); r != retry_at_.end() && Clock::now() < r->second) continue;
      seen_.insert(j.job_id());
      start(j);
    }
    return true;
  }

  void start(const v1::JobStatus& j) {
    const RecordedOutput r = from_job_output(j.output());
    std::printf("collect: job %s '%s': frames to %s\n", j.job_id().c_str(), j.name().c_str(), r.pattern.c_str());
    std::fflush(stdout);
    auto d = std::make_unique<Delivery>();
    Delivery* dp = d.get();
    // The options live in the thread: watch_job keeps references to them.
    dp->thread = std::thread([this, dp, id = j.job_id(), name = j.name(), first = j.first_frame(), r] {
      const WatchOptions o{r.pattern, name, true, r.color, r.error_channels, 0, false, &dp->refused};
      try {
        check_output_writable(o.output, first);
        watch_job(client_, id, o);
      } catch (const CommandError& e) {
        dp->error = e.message;
      } catch (const std::exception& e) {
        dp->error = e.what();
      }
      dp->finished = true;
    });
    active_.emplace(j.job_id(), std::move(d));
  }

  void reap() {
    for (auto it = active_.begin(); it != active_.end();) {
      Delivery& d = *it->second;
      if (!d.finished) {
        ++it;
        continue;
      }
      d.thread.join();
      if (d.error.empty()) {
        ++delivered_;
      } else if (d.refused == grpc::StatusCode::PERMISSION_DENIED || d.refused == grpc::StatusCode::NOT_FOUND) {
        // Another identity's job (this collector's token has no rights over it), or one gone:
        // not this collector's to deliver, now or later. Said once; --owner avoids it.
        std::printf("collect: job %s is not collected here: %s\n", it->first.c_str(), d.error.c_str());
        std::fflush(stdout);
        retry_at_[it->first] = Clock::time_point::max();
      } else {
        // The frames stay on the coordinator: try again later (a share that was full or not
        // mounted may be back), saying why each time.
        ++failed_;
        spdlog::error("collect: job {}: {}; trying again in {} s", it->first, d.error, kRetry.count());
        retry_at_[it->first] = Clock::now() + kRetry;
      }
      it = active_.erase(it);
    }
  }

  static constexpr std::chrono::seconds kRetry{60};
  FarmClient& client_;
  const CollectArgs& a_;
  std::map<std::string, std::unique_ptr<Delivery>> active_;
  std::map<std::string, Clock::time_point> retry_at_;
  std::set<std::string> seen_;
  int delivered_ = 0, failed_ = 0;
};

int run_collect(const CollectArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  say_on_interrupt(
      "tessera collect stopped: the frames it had not written stay on the coordinator for the next "
      "collector or `tessera watch JOB`");
  return Collector(client, a).run();
}

}  // namespace

void register_collect_command(CLI::App& app) {
  auto a = std::make_shared<CollectArgs>();
  CLI::App* cmd = app.add_subcommand(
      "collect",
      "Deliver finished frames of every job with a recorded output (submit -o) to its files, and keep doing so");
  add_coordinator_option(cmd, &a->coordinator, &a->security);
  cmd->add_option("--under", a->under,
                  "Only jobs whose recorded output path starts with this prefix (repeatable), e.g. the share this "
                  "machine mounts");
  cmd->add_option("--owner", a->owners,
                  "Only jobs submitted by this client identity (repeatable): token:NAME for a named client token, "
                  "cn:NAME for a TLS client certificate, as `tessera status --json` shows it in \"owner\"");
  cmd->add_option("--poll", a->poll_seconds, "Seconds between looks for new jobs")
      ->check(CLI::Range(0.05, 3600.0))
      ->capture_default_str();
  cmd->add_flag("--once", a->once,
                "Deliver the jobs on the coordinator now, to their end, then exit (status 1 if one failed)");
  cmd->callback([a] { guarded("collect", [&] { return run_collect(*a); }); });
}

}  // namespace tessera::cli

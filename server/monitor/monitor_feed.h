// SPDX-License-Identifier: Apache-2.0
// What the web monitor shows beyond the coordinator's snapshot: per-frame times and estimated
// errors, the preview of frames as they converge, which worker rendered which tile, and the
// faults counted against each worker.
//
// Cost when no browser is open: nothing but one clock read per finished tile. The feed is
// active for kActiveFor after the last monitor request (the page polls every second); while it
// is inactive, finished tiles are not looked at. While it is active, each finished tile costs
// one queue append under the coordinator's mutex; the tiles are decoded later, by the HTTP
// thread that answers the next request. Coming back after a pause, the feed starts over from
// the tiles the coordinator still holds (frames not yet delivered to their client).
//
// Pixels (12 bytes a pixel) are kept while a page is open for the live jobs, and for kActiveFor
// after a job page was last looked at (so a job that just finished, and left the coordinator's
// memory with its frames delivered, still shows its frame): at most kMaxPreviews jobs,
// kMaxFrames frames each. Statistics, a few numbers a frame, for every job in memory and the
// last kRecentEnded that ended.
#pragma once

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include "farm_view.h"
#include "frame_canvas.h"

namespace tessera::server {

class MonitorFeed : public SchedulerListener {
 public:
  static constexpr std::chrono::seconds kActiveFor{30};
  static constexpr size_t kMaxPreviews = 8;
  static constexpr size_t kMaxFrames = 2;
  static constexpr size_t kMaxPending = 200000;  // tiles queued for decoding; beyond: dropped

  // Registers itself as an observer of `coordinator`, which must outlive it; unregisters when
  // destroyed.
  explicit MonitorFeed(FarmView& coordinator);
  ~MonitorFeed() override;
  MonitorFeed(const MonitorFeed&) = delete;
  MonitorFeed& operator=(const MonitorFeed&) = delete;

  // The jobs, workers and ray servers, as the monitor's main page shows them.
  nlohmann::json farm();
  // One job: its status, its frames' statistics, and the preview's tile map (frame `frame`, or
  // the newest frame with tiles). nullopt for a job not in memory.
  std::optional<nlohmann::json> job(const std::string& id, std::optional<int> frame);
  // The preview PNG of a frame of the job (the newest frame with tiles when none is given);
  // nullopt when the coordinator has no tile of it in memory.
  std::optional<std::string> preview(const std::string& id, std::optional<int> frame,
                                     const color::ToneMapSettings& tonemap);

  // SchedulerListener (under the coordinator's mutex).
  void tile_finished(const TileKey& key, const TileOutput& out, WorkerId) override;
  void worker_faulted(const JobId&, const WorkerStats& w, std::string_view reason, int faults,
                      bool blocklisted) override;
  void job_state_changed(const JobId& id, JobState state) override;
  void job_submitted(const JobSnapshot& s) override;

 private:
  struct Pending {
    TileKey key;
    std::shared_ptr<const std::string> payload;
    double arrived = 0;
  };
  struct JobFeed {
    bool seeded = false;  // the tiles the coordinator held when the feed first saw the job are in
    std::map<int, std::set<int>> tiles_seen;  // frame -> tile indexes decoded into the stats
    std::map<int, FrameStats> frames;
    double variance_sum = 0;
    int64_t pixels = 0;
  };
  struct Geometry {
    int width = 0, height = 0, tile_size = 0;
  };
  struct Preview {
    Geometry geometry;
    std::map<int, FrameCanvas> frames;
    bool seeded = false;
    std::chrono::steady_clock::time_point asked;
  };
  struct WorkerFaults {
    int faults = 0;
    std::string last_reason;
  };

  // Marks the feed active, takes a snapshot, decodes the tiles finished since the last request
  // and, for jobs (and the preview of `preview_job`) not seen yet, the tiles the coordinator
  // still holds. After a pause it first forgets what it knew (it missed tiles meanwhile).
  FarmSnapshot catch_up(const std::optional<JobId>& preview_job = std::nullopt);
  // Adds a finished tile to its job's statistics and to its preview; `may_preview` creates the
  // preview when the job has none (tiles of live jobs: a page opened later still shows them).
  void decode_locked(const TileKey& key, const std::string& payload, double arrived, bool may_preview);
  // The job's preview, made when its geometry is known (evicting the one looked at longest ago).
  Preview* preview_locked(const JobId& id);
  // A job as the pages show it (the coordinator's JobStatus, plus ETA, rates and what the feed
  // measured).
  nlohmann::json job_json_locked(const tessera::v1::JobStatus& s, const std::string& owner) const;
  // The status of a job that left the coordinator's memory (read once from its database).
  std::optional<nlohmann::json> ended_job(const JobId& id);
  static double now_s();

  FarmView& coordinator_;
  std::atomic<int64_t> active_until_{0};  // steady-clock nanoseconds

  std::mutex pending_mu_;  // taken under the coordinator's mutex: nothing else is done under it
  std::deque<Pending> pending_;
  std::vector<std::pair<JobId, Geometry>> pending_jobs_;  // submitted while active
  int64_t dropped_ = 0;

  // Lock order: the coordinator's mutex, then these. So none is held while calling the
  // coordinator (snapshot, finished_tiles).
  std::mutex mu_;  // jobs_, previews_
  std::map<JobId, JobFeed> jobs_;
  std::map<JobId, Preview> previews_;
  std::map<JobId, Geometry> geometry_;  // frame size and tile size of the jobs the feed knows
  std::mutex events_mu_;
  std::map<std::string, WorkerFaults> faults_;  // by worker name; counted whether active or not
  // Jobs that ended lately, newest last: they stay on the page after they leave the
  // coordinator's memory (which a job whose frames were all delivered does at once).
  static constexpr size_t kRecentEnded = 20;
  std::deque<JobId> ended_;
  std::map<JobId, nlohmann::json> ended_status_;  // cached: an ended job does not change
};

}  // namespace tessera::server

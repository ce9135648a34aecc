// SPDX-License-Identifier: Apache-2.0
#include "monitor_feed.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>

namespace tessera::server {

namespace {

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

double seconds_between(TimePoint a, TimePoint b) { return std::chrono::duration<double>(b - a).count(); }

double variance_sum(const std::string& bytes, int64_t* pixels) {
  double sum = 0;
  const size_t n = bytes.size() / sizeof(float);
  for (size_t i = 0; i < n; ++i) {
    float v;
    std::memcpy(&v, bytes.data() + i * sizeof(float), sizeof v);
    sum += double(v);
  }
  *pixels += int64_t(n);
  return sum;
}

}  // namespace

double MonitorFeed::now_s() { return double(steady_ns()) * 1e-9; }

MonitorFeed::MonitorFeed(FarmView& coordinator) : coordinator_(coordinator) { coordinator.add_observer(this); }

MonitorFeed::~MonitorFeed() { coordinator_.remove_observer(this); }

void MonitorFeed::tile_finished(const TileKey& key, const TileOutput& out, WorkerId) {
  const int64_t now = steady_ns();
  if (now > active_until_.load(std::memory_order_relaxed)) return;  // no browser open: no cost
  std::lock_guard lock(pending_mu_);
  if (pending_.size() >= kMaxPending) {
    ++dropped_;
    return;
  }
  pending_.push_back({key, out.payload, double(now) * 1e-9});
}

void MonitorFeed::job_state_changed(const JobId& id, JobState state) {
  if (!job_ended(state)) return;
  std::lock_guard lock(events_mu_);
  ended_.push_back(id);
  if (ended_.size() > kRecentEnded) {
    ended_status_.erase(ended_.front());
    ended_.pop_front();
  }
}

void MonitorFeed::worker_faulted(const JobId& job, const WorkerStats& w, std::string_view reason, int, bool) {
  std::lock_guard lock(events_mu_);
  WorkerFaults& f = faults_[w.info.name];
  ++f.faults;
  f.last_reason = "job " + job + ": " + std::string(reason);
}

void MonitorFeed::job_submitted(const JobSnapshot& s) {
  if (steady_ns() > active_until_.load(std::memory_order_relaxed)) return;
  std::lock_guard lock(pending_mu_);
  pending_jobs_.emplace_back(s.id, Geometry{s.spec.width, s.spec.height, s.spec.tile_size});
}

FarmSnapshot MonitorFeed::catch_up(const std::optional<JobId>& preview_job) {
  const int64_t now = steady_ns();
  const bool was_idle = now > active_until_.exchange(
                                  now + std::chrono::duration_cast<std::chrono::nanoseconds>(kActiveFor).count());
  FarmSnapshot snap = coordinator_.snapshot();
  std::deque<Pending> pending;
  std::vector<std::pair<JobId, Geometry>> submitted;
  {
    std::lock_guard lock(pending_mu_);
    pending.swap(pending_);
    submitted.swap(pending_jobs_);
    if (dropped_) spdlog::warn("monitor: {} finished tiles were not shown (the preview fell behind)", dropped_);
    dropped_ = 0;
  }
  std::set<JobId> keep;  // jobs whose statistics stay: in memory, or ended lately
  {
    std::lock_guard lock(events_mu_);
    keep.insert(ended_.begin(), ended_.end());
  }
  std::set<JobId> live;
  for (const JobSnapshot& j : snap.jobs) {
    keep.insert(j.id);
    if (!job_ended(j.state)) live.insert(j.id);
  }
  std::vector<JobId> to_seed;
  {
    std::lock_guard lock(mu_);
    if (was_idle) {
      jobs_.clear();
      previews_.clear();
      geometry_.clear();
    }
    for (auto& [id, g] : submitted) geometry_[id] = g;
    for (const JobSnapshot& j : snap.jobs) geometry_[j.id] = {j.spec.width, j.spec.height, j.spec.tile_size};
    for (const Pending& p : pending) decode_locked(p.key, *p.payload, p.arrived, true);
    // Live jobs keep their previews while a page is open; other previews stay kActiveFor after
    // their page was last looked at (so a job that just finished still shows its frame).
    const auto t = Clock::now();
    for (auto& [id, p] : previews_) {
      if (live.count(id) || (preview_job && id == *preview_job)) p.asked = t;
    }
    if (preview_job && !previews_.count(*preview_job) && keep.count(*preview_job)) {
      if (Preview* p = preview_locked(*preview_job)) p->asked = t;
    }
    std::erase_if(previews_, [&](const auto& kv) { return kv.second.asked < t - kActiveFor; });
    std::erase_if(jobs_, [&](const auto& kv) { return !keep.count(kv.first) && !previews_.count(kv.first); });
    std::erase_if(geometry_, [&](const auto& kv) { return !keep.count(kv.first) && !jobs_.count(kv.first); });
    for (const JobSnapshot& j : snap.jobs) {
      const bool stats = !jobs_[j.id].seeded;
      auto p = previews_.find(j.id);
      if (stats || (p != previews_.end() && !p->second.seeded)) to_seed.push_back(j.id);
    }
  }
  // The coordinator's mutex is taken here, ours is not (lock order: see the header).
  for (const JobId& id : to_seed) {
    const auto tiles = coordinator_.finished_tiles(id);
    std::lock_guard lock(mu_);
    const double t = now_s();
    for (const auto& [key, out] : tiles) {
      if (out.payload) decode_locked(key, *out.payload, t, live.count(id) > 0);
    }
    if (auto it = jobs_.find(id); it != jobs_.end()) it->second.seeded = true;
    if (auto it = previews_.find(id); it != previews_.end()) it->second.seeded = true;
  }
  return snap;
}

MonitorFeed::Preview* MonitorFeed::preview_locked(const JobId& id) {
  if (auto it = previews_.find(id); it != previews_.end()) return &it->second;
  const auto g = geometry_.find(id);
  if (g == geometry_.end()) return nullptr;
  if (previews_.size() >= kMaxPreviews) {
    // The preview looked at longest ago makes room.
    auto oldest = previews_.begin();
    for (auto p = previews_.begin(); p != previews_.end(); ++p) {
      if (p->second.asked < oldest->second.asked) oldest = p;
    }
    previews_.erase(oldest);
  }
  Preview& p = previews_[id];
  p.geometry = g->second;
  p.asked = Clock::now();
  return &p;
}

void MonitorFeed::decode_locked(const TileKey& key, const std::string& payload, double arrived, bool may_preview) {
  JobFeed& job = jobs_[key.job];
  const bool want_stats = !job.tiles_seen[key.frame].count(key.tile);
  FrameCanvas* canvas = nullptr;
  Preview* preview = may_preview ? preview_locked(key.job) : nullptr;
  if (!preview) {
    auto it = previews_.find(key.job);
    if (it != previews_.end()) preview = &it->second;
  }
  if (preview) {
    auto& frames = preview->frames;
    auto it = frames.find(key.frame);
    if (it == frames.end() && (frames.size() < kMaxFrames || key.frame > frames.begin()->first)) {
      if (frames.size() >= kMaxFrames) frames.erase(frames.begin());  // the oldest frame makes room
      const Geometry& g = preview->geometry;
      it = frames.emplace(key.frame, FrameCanvas(g.width, g.height, g.tile_size)).first;
    }
    if (it != frames.end() && !it->second.has(key.tile)) canvas = &it->second;
  }
  if (!want_stats && !canvas) return;
  tessera::v1::TileData tile;
  if (!tile.ParseFromString(payload)) {
    spdlog::warn("monitor: job {} frame {} tile {} does not parse; not shown", key.job, key.frame, key.tile);
    return;
  }
  if (canvas) {
    if (std::string err = canvas->add(tile); !err.empty()) {
      spdlog::warn("monitor: job {} frame {}: {}; not shown", key.job, key.frame, err);
    }
  }
  if (want_stats) {
    JobFeed& f = job;
    f.tiles_seen[key.frame].insert(key.tile);
    FrameStats& fs = f.frames[key.frame];
    if (fs.tiles == 0 || arrived < fs.first_seen) fs.first_seen = arrived;
    fs.last_seen = std::max(fs.last_seen, arrived);
    ++fs.tiles;
    fs.tile_seconds += tile.seconds();
    int64_t pixels = 0;
    const double v = variance_sum(tile.variance(), &pixels);
    fs.variance_sum += v;
    fs.pixels += pixels;
    f.variance_sum += v;
    f.pixels += pixels;
  }
}

nlohmann::json MonitorFeed::job_json_locked(const tessera::v1::JobStatus& s, const std::string& owner) const {
  using nlohmann::json;
  // "JOB_STATE_RUNNING" -> "running", the names job_state_name() gives.
  std::string state = tessera::v1::JobState_Name(s.state()).substr(std::string_view("JOB_STATE_").size());
  for (char& c : state) c = char(std::tolower(static_cast<unsigned char>(c)));
  const double elapsed = s.elapsed_seconds();
  json j{{"id", s.job_id()},
         {"name", s.name()},
         {"owner", owner},
         {"state", state},
         {"priority", s.priority()},
         {"first_frame", s.first_frame()},
         {"last_frame", s.last_frame()},
         {"frames_done", s.frames_done_size()},
         {"width", s.width()},
         {"height", s.height()},
         {"spp", s.spp()},
         {"tile_size", s.tile_size()},
         {"tiles_per_frame", s.tiles_per_frame()},
         {"tiles_total", s.tiles_total()},
         {"tiles_done", s.tiles_done()},
         {"tiles_leased", s.tiles_leased()},
         {"progress", s.tiles_total() ? double(s.tiles_done()) / double(s.tiles_total()) : 0.0},
         {"elapsed_seconds", elapsed},
         {"rays", s.rays()},
         {"mrays_per_second", elapsed > 0 ? double(s.rays()) / elapsed / 1e6 : 0.0},
         {"error", s.error()},
         {"output", s.has_output() ? json(s.output().pattern()) : json(nullptr)},
         {"frames_acknowledged", s.frames_acknowledged_size()},
         {"blocklisted", std::vector<std::string>(s.blocklisted_workers().begin(), s.blocklisted_workers().end())}};
  // ETA: the rest of the tiles at the job's average pace so far.
  j["eta_seconds"] = (s.state() == tessera::v1::JOB_STATE_RUNNING && s.tiles_done() > 0)
                         ? json(elapsed * double(s.tiles_total() - s.tiles_done()) / double(s.tiles_done()))
                         : json(nullptr);
  auto f = jobs_.find(s.job_id());
  j["estimated_rmse"] = (f != jobs_.end() && f->second.pixels > 0)
                            ? json(std::sqrt(f->second.variance_sum / double(f->second.pixels)))
                            : json(nullptr);
  return j;
}

std::optional<nlohmann::json> MonitorFeed::ended_job(const JobId& id) {
  {
    std::lock_guard lock(events_mu_);
    if (auto it = ended_status_.find(id); it != ended_status_.end()) return it->second;
  }
  tessera::v1::JobStatus status;
  if (!coordinator_.get_job(id, &status).ok()) return std::nullopt;
  const std::string owner = coordinator_.job_owner(id).value_or("");
  nlohmann::json j;
  {
    std::lock_guard lock(mu_);
    j = job_json_locked(status, owner);
  }
  std::lock_guard lock(events_mu_);
  if (std::find(ended_.begin(), ended_.end(), id) != ended_.end()) ended_status_[id] = j;
  return j;
}

nlohmann::json MonitorFeed::farm() {
  using nlohmann::json;
  const FarmSnapshot snap = catch_up();
  json jobs = json::array(), workers = json::array();
  std::set<JobId> listed;
  {
    std::lock_guard lock(mu_);
    // Newest first: the job just submitted is the one looked for.
    for (auto it = snap.jobs.rbegin(); it != snap.jobs.rend(); ++it) {
      tessera::v1::JobStatus status;
      coordinator_.status_of(*it, &status);
      jobs.push_back(job_json_locked(status, it->spec.owner));
      listed.insert(it->id);
    }
  }
  std::vector<JobId> recent;
  {
    std::lock_guard lock(events_mu_);
    recent.assign(ended_.rbegin(), ended_.rend());
  }
  for (const JobId& id : recent) {
    if (listed.count(id)) continue;
    if (auto j = ended_job(id)) jobs.push_back(std::move(*j));
  }
  std::map<std::string, std::vector<std::string>> blocklisted;  // worker name -> jobs
  for (const JobSnapshot& j : snap.jobs) {
    for (const std::string& w : j.blocklisted) blocklisted[w].push_back(j.id);
  }
  std::lock_guard lock(events_mu_);
  for (const WorkerStats& w : snap.workers) {
    const double connected = seconds_between(w.connected, Clock::now());
    const auto f = faults_.find(w.info.name);
    workers.push_back({{"id", w.id},
                       {"name", w.info.name},
                       {"peer", w.info.peer},
                       {"threads", w.info.threads},
                       {"embree_isa", w.info.embree_isa},
                       {"state", w.in_flight > 0 ? "rendering" : "idle"},
                       {"tiles_held", w.in_flight},
                       {"tiles_done", w.tiles_done},
                       {"tiles_per_second", connected > 0 ? double(w.tiles_done) / connected : 0.0},
                       {"mrays_per_second", w.seconds > 0 ? double(w.rays) / w.seconds / 1e6 : 0.0},
                       {"connected_seconds", connected},
                       {"faults", f == faults_.end() ? 0 : f->second.faults},
                       {"last_fault", f == faults_.end() ? "" : f->second.last_reason},
                       {"blocklisted_for", blocklisted[w.info.name]}});
  }
  // Ray servers (tessera-rays) announced to the coordinator: their registry's lock is a leaf.
  json ray_servers = json::array();
  tessera::v1::ListRayServersResponse announced;
  coordinator_.list_ray_servers(&announced);
  for (const auto& r : announced.servers()) {
    const auto& d = r.server();
    ray_servers.push_back({{"id", d.server_id()},
                           {"address", d.address()},
                           {"threads", d.threads()},
                           {"embree_isa", d.embree_isa()},
                           {"tls", d.tls()},
                           {"requests", d.requests()},
                           {"rays", d.rays()},
                           {"rays_in_flight", d.rays_in_flight()},
                           {"up_seconds", r.up_seconds()},
                           {"since_announcement_seconds", r.since_announcement_seconds()}});
  }
  const json delivery{{"frames", snap.delivery.frames()},
                      {"bytes", snap.delivery.bytes()},
                      {"oldest_seconds", snap.delivery.oldest_seconds()},
                      {"limit_bytes", snap.delivery.limit_bytes()}};
  return json{{"jobs", jobs},
              {"workers", workers},
              {"ray_servers", ray_servers},
              {"tiles_queued", snap.tiles_queued},
              {"delivery", delivery}};
}

std::optional<nlohmann::json> MonitorFeed::job(const std::string& id, std::optional<int> frame) {
  using nlohmann::json;
  const FarmSnapshot snap = catch_up(id);
  const auto s = std::find_if(snap.jobs.begin(), snap.jobs.end(), [&](const JobSnapshot& j) { return j.id == id; });
  json j;
  if (s == snap.jobs.end()) {
    auto ended = ended_job(id);  // left memory: its status from the database, what the feed saw of it
    if (!ended) return std::nullopt;
    j = std::move(*ended);
  }
  std::lock_guard lock(mu_);
  if (s != snap.jobs.end()) {
    tessera::v1::JobStatus status;
    coordinator_.status_of(*s, &status);
    j = job_json_locked(status, s->spec.owner);
  } else if (auto f = jobs_.find(id); f != jobs_.end() && f->second.pixels > 0) {
    j["estimated_rmse"] = std::sqrt(f->second.variance_sum / double(f->second.pixels));
  }
  const int tiles_per_frame = j["tiles_per_frame"].get<int>();
  json frames = json::array();
  if (auto f = jobs_.find(id); f != jobs_.end()) {
    for (const auto& [n, fs] : f->second.frames) {
      frames.push_back({{"frame", n},
                        {"tiles", fs.tiles},
                        {"complete", fs.tiles == tiles_per_frame},
                        {"wall_seconds", fs.last_seen - fs.first_seen},
                        {"tile_seconds", fs.tile_seconds},
                        {"estimated_rmse", fs.pixels > 0 ? json(fs.estimated_rmse()) : json(nullptr)}});
    }
  }
  j["frames"] = frames;
  json preview = nullptr;
  if (auto p = previews_.find(id); p != previews_.end() && !p->second.frames.empty()) {
    auto c = frame ? p->second.frames.find(*frame) : std::prev(p->second.frames.end());
    if (c != p->second.frames.end()) {
      json frames_shown = json::array();
      for (const auto& [n, canvas] : p->second.frames) frames_shown.push_back(n);
      preview = {{"frame", c->first},
                 {"frames", frames_shown},
                 {"tiles_done", c->second.tiles_done()},
                 {"tiles_x", c->second.tiles_x()},
                 {"tiles_y", c->second.tiles_y()},
                 {"tile_workers", c->second.worker_of()},
                 {"workers", c->second.workers()}};
    }
  }
  j["preview"] = preview;
  return j;
}

std::optional<std::string> MonitorFeed::preview(const std::string& id, std::optional<int> frame,
                                                const color::ToneMapSettings& tonemap) {
  catch_up(id);
  std::lock_guard lock(mu_);
  auto p = previews_.find(id);
  if (p == previews_.end() || p->second.frames.empty()) return std::nullopt;
  auto c = frame ? p->second.frames.find(*frame) : std::prev(p->second.frames.end());
  if (c == p->second.frames.end()) return std::nullopt;
  return c->second.png(tonemap);
}

}  // namespace tessera::server

// `tessera submit | watch | status | cancel | priority | workers | rayservers`: the render farm's client side.
// Exit codes: 0 done, 1 failure (network, I/O), 2 bad input (scene, arguments), 3 job cancelled.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "commands.h"
#include "farm/bundle.h"
#include "farm/codec.h"
#include "bundle_upload.h"
#include "farm_client.h"
#include "farm_frames.h"
#include "image_options.h"
#include "image/output_path.h"
#include "output_flags.h"
#include "sample_report.h"
#include "scene/scene_parser.h"

namespace tessera::cli {

namespace v1 = tessera::v1;
namespace fs = std::filesystem;

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitCancelled = 3;

struct FarmError {
  int code;
  std::string message;
};

// A failed call about one job: an unknown job id is the user's input error (exit 2).
FarmError job_error(const FarmClient& client, const grpc::Status& s, const std::string& what) {
  return FarmError{s.error_code() == grpc::StatusCode::NOT_FOUND ? kExitBadInput : kExitFailure,
                   client.describe(s, what)};
}

// The client for a command's --coordinator and security flags; bad certificate or token files
// are input errors (exit 2).
FarmClient connect(const std::string& coordinator, const SecurityFlags& flags) {
  try {
    return FarmClient(resolve_coordinator(coordinator), resolve_security(flags));
  } catch (const std::runtime_error& e) {
    throw FarmError{kExitBadInput, e.what()};
  }
}

const char* state_name(v1::JobState s) {
  switch (s) {
    case v1::JOB_STATE_QUEUED: return "queued";
    case v1::JOB_STATE_RUNNING: return "running";
    case v1::JOB_STATE_DONE: return "done";
    case v1::JOB_STATE_CANCELLED: return "cancelled";
    case v1::JOB_STATE_FAILED: return "failed";
    default: return "unknown";
  }
}

std::string fmt_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  char buf[32];
  const int t = int(std::lround(s));
  if (t >= 3600) {
    std::snprintf(buf, sizeof buf, "%d:%02d:%02d", t / 3600, t / 60 % 60, t % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%d:%02d", t / 60, t % 60);
  }
  return buf;
}

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Fails early, before anything is submitted, if the output cannot be written.
void check_output_writable(const std::string& pattern, int frame) {
  const fs::path out = frame_output_path(pattern, frame);
  fs::path dir = out.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw FarmError{kExitFailure, "output '" + pattern + "' is not writable: cannot create " + dir.string() + ": " + ec.message()};
  const fs::path probe = dir / (".tessera-write-test-" + std::to_string(getpid()));
  {
    std::ofstream f(probe);
    if (!f) throw FarmError{kExitFailure, "output '" + pattern + "' is not writable: cannot create files in " + dir.string()};
  }
  fs::remove(probe, ec);
}

// ---------------------------------------------------------------------------------------------
// Progress display: a bar on a terminal, a plain line every few seconds otherwise (logs, CI).

class Progress {
 public:
  Progress(int64_t total, int64_t done_before) : total_(total), base_(done_before), tty_(isatty(fileno(stderr))) {
    start_ = now_s();
  }
  // `error`: the estimated error so far, e.g. "est. RMSE 0.0021 (target 0.002)"; may be empty.
  void update(int64_t received, uint64_t rays, const std::string& error, bool force = false) {
    const double t = now_s();
    if (!force && t - last_ < (tty_ ? 0.2 : 5.0)) return;
    last_ = t;
    const double el = t - start_;
    const int64_t done = std::min(total_, base_ + received);
    const double rate = el > 0 ? double(received) / el : 0;
    const double eta = rate > 0 ? double(total_ - done) / rate : NAN;
    const double mrays = el > 0 ? double(rays) / el / 1e6 : 0;
    if (tty_) {
      const int width = 30;
      const int fill = total_ > 0 ? int(double(done) / double(total_) * width) : width;
      std::fprintf(stderr, "\r[%s%s] %lld/%lld tiles  %.1f Mrays/s  %s%sETA %s   ",
                   std::string(size_t(fill), '#').c_str(), std::string(size_t(width - fill), '.').c_str(),
                   (long long)done, (long long)total_, mrays, error.c_str(), error.empty() ? "" : "  ",
                   fmt_duration(eta).c_str());
    } else {
      std::fprintf(stderr, "progress: %lld/%lld tiles (%.0f%%), %.1f Mrays/s, %s%sETA %s\n", (long long)done,
                   (long long)total_, total_ ? 100.0 * double(done) / double(total_) : 100.0, mrays, error.c_str(),
                   error.empty() ? "" : ", ", fmt_duration(eta).c_str());
    }
    std::fflush(stderr);
  }
  void clear_line() {
    if (tty_) std::fprintf(stderr, "\r%80s\r", "");
  }

 private:
  int64_t total_, base_;
  bool tty_;
  double start_ = 0, last_ = -1e9;
};

// ---------------------------------------------------------------------------------------------
// Watching: receives the job's tiles, writes each frame when complete, acknowledges it.

struct WatchOptions {
  std::string output;        // empty: progress only, frames are neither written nor acknowledged
  std::string scene_name;
  bool quiet = false;
  color::OutputOptions color;  // tone mapping / format when the output is not a float EXR
  bool error_channels = false;  // error.Y and spp.Y layers in each EXR
  double preview_every = 0;     // seconds between previews of frames in progress; 0: none
};

// The progress display's error: the estimate over the pixels received so far, and the target.
std::string progress_error(const FrameAssembler& frames) {
  if (frames.tiles_received() == 0) return {};
  char buf[96];
  if (frames.settings().adaptive()) {
    std::snprintf(buf, sizeof buf, "est. RMSE %.3g (target %.3g)", frames.running_estimated_rmse(),
                  frames.settings().target_rmse);
  } else {
    std::snprintf(buf, sizeof buf, "est. RMSE %.3g", frames.running_estimated_rmse());
  }
  return buf;
}

// "64 spp" for a uniform job, "target RMSE 0.002 (spp 16-1024)" for a target-error one.
std::string describe_sampling(const v1::JobStatus& st) {
  const ImageSettings s = job_image_settings(st);
  if (!s.adaptive()) return std::to_string(st.spp()) + " spp";
  char buf[96];
  std::snprintf(buf, sizeof buf, "target RMSE %.3g (spp %d-%d)", s.target_rmse, s.min_spp, s.max_spp);
  return buf;
}

int watch_job(FarmClient& client, const std::string& job_id, const WatchOptions& o) {
  std::optional<FrameAssembler> frames;
  std::optional<Progress> progress;
  v1::JobStatus final_status;
  std::set<int> delivered_before;  // frames acknowledged by a client (maybe this one)
  int reconnects = 0;
  double total_start = now_s();
  double last_preview = now_s();
  while (true) {
    // Long-lived stream: no short deadline (a job may take days); keepalive pings on the
    // channel detect a dead coordinator, and a lost stream is re-attached below.
    auto ctx = FarmClient::context(std::chrono::hours(24 * 30));
    v1::WatchJobRequest req;
    req.set_job_id(job_id);
    auto stream = client.stub().WatchJob(ctx.get(), req);
    v1::WatchJobEvent ev;
    bool ended = false;
    while (stream->Read(&ev)) {
      if (ev.has_status()) {
        const auto& st = ev.status();
        reconnects = 0;  // attached again: a coordinator restart costs one attempt, not a budget
        if (!frames) {
          frames.emplace(st);
          if (!o.quiet) {
            std::printf("job %s: %s, frames %d-%d, %dx%d, %s, %lld tiles (%lld done)\n", st.job_id().c_str(),
                        state_name(st.state()), st.first_frame(), st.last_frame(), st.width(), st.height(),
                        describe_sampling(st).c_str(), (long long)st.tiles_total(), (long long)st.tiles_done());
            for (int f : st.frames_acknowledged()) {
              std::printf("frame %d was already delivered to an earlier client\n", f);
            }
            std::fflush(stdout);
          }
          // Unacknowledged finished tiles are re-sent on this stream: count from the frames
          // already delivered to an earlier client.
          progress.emplace(st.tiles_total(), int64_t(st.frames_acknowledged_size()) * st.tiles_per_frame());
        }
        delivered_before.insert(st.frames_acknowledged().begin(), st.frames_acknowledged().end());
        if (st.state() == v1::JOB_STATE_DONE || st.state() == v1::JOB_STATE_CANCELLED ||
            st.state() == v1::JOB_STATE_FAILED) {
          ended = true;
          final_status = st;
        }
      } else if (ev.has_tile()) {
        std::string err;
        frames->add(ev.tile(), &err);
        if (!err.empty()) spdlog::warn("ignored a tile: {}", err);
        if (!o.quiet) progress->update(frames->tiles_received(), frames->rays_received(), progress_error(*frames));
        if (o.preview_every > 0 && !o.output.empty() && now_s() - last_preview >= o.preview_every) {
          last_preview = now_s();
          try {
            frames->write_previews(o.output, o.color);
          } catch (const std::exception& e) {
            spdlog::warn("cannot write a preview: {}", e.what());  // the frames themselves still come
          }
        }
      } else if (ev.event_case() == v1::WatchJobEvent::kFrameDone) {
        const int f = ev.frame_done();
        if (!o.output.empty() && frames->written(f)) {
          // Re-sent after a coordinator restart lost our acknowledgement: acknowledge it again so
          // the coordinator can release the frame.
          v1::AckFrameRequest ack;
          ack.set_job_id(job_id);
          ack.set_frame(f);
          v1::AckFrameResponse ack_resp;
          auto actx = client.context();
          client.stub().AckFrame(actx.get(), ack, &ack_resp);
          continue;
        }
        if (o.output.empty()) continue;
        if (!frames->complete(f)) {
          // Never write or acknowledge a frame with holes: the coordinator keeps its tiles.
          spdlog::error("frame {} reported done but {}: not written, not acknowledged", f, frames->missing_tiles(f));
          continue;
        }
        FrameReport rep;
        try {
          rep = frames->write(f, o.output, o.scene_name, o.color, o.error_channels);
        } catch (const std::exception& e) {
          throw FarmError{kExitFailure, std::string("cannot write frame ") + std::to_string(f) + ": " + e.what()};
        }
        if (!o.quiet) progress->clear_line();
        const double secs = rep.wall_seconds > 0.05 ? rep.wall_seconds : rep.tile_seconds;
        std::printf("%s: frame %d: %.3f s, %.2f Mrays/s, %s, %zu worker(s)\n", rep.path.c_str(), f, secs,
                    secs > 0 ? double(rep.rays) / secs / 1e6 : 0.0,
                    describe_samples(rep.samples, frames->settings()).c_str(), rep.workers.size());
        std::fflush(stdout);
        if (const std::string w = target_warning(rep.samples, frames->settings()); !w.empty()) {
          spdlog::warn("frame {}: {}", f, w);
        }
        v1::AckFrameRequest ack;
        ack.set_job_id(job_id);
        ack.set_frame(f);
        v1::AckFrameResponse ack_resp;
        auto actx = client.context();
        grpc::Status s = client.stub().AckFrame(actx.get(), ack, &ack_resp);
        if (!s.ok()) spdlog::warn("{}", client.describe(s, "acknowledging frame " + std::to_string(f)));
      }
    }
    grpc::Status s = stream->Finish();
    if (s.ok() && ended) break;
    if (s.error_code() == grpc::StatusCode::NOT_FOUND || s.error_code() == grpc::StatusCode::INVALID_ARGUMENT) {
      throw FarmError{kExitBadInput, s.error_message()};
    }
    // Lost the coordinator mid-job: re-attach (finished tiles are kept for us), a few times.
    if ((s.error_code() == grpc::StatusCode::UNAVAILABLE || s.ok()) && frames && reconnects < 30) {
      ++reconnects;
      spdlog::warn("lost the watch stream ({}); re-attaching", s.error_message());
      // Back as soon as the coordinator listens again (at most the pause below).
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      client.wait_for_coordinator(std::chrono::seconds(std::min(reconnects, 5)));
      continue;
    }
    throw FarmError{kExitFailure, client.describe(s, "watching job " + job_id)};
  }
  if (!o.quiet) {
    progress->update(frames->tiles_received(), frames->rays_received(), progress_error(*frames), true);
    progress->clear_line();
  }
  const double total = now_s() - total_start;
  if (final_status.state() == v1::JOB_STATE_FAILED) {
    throw FarmError{kExitFailure, "job " + job_id + " failed: " + final_status.error()};
  }
  if (final_status.state() == v1::JOB_STATE_CANCELLED) {
    std::printf("job %s was cancelled\n", job_id.c_str());
    return kExitCancelled;
  }
  // "Done" is only success when every frame reached a file (here or through an earlier client).
  if (!o.output.empty()) {
    if (const std::string lost = frames->frames_not_written(delivered_before); !lost.empty()) {
      throw FarmError{kExitFailure, "job " + job_id + " is done on the coordinator, but not every frame arrived "
                                    "complete, so these were not written: " + lost};
    }
  }
  std::printf("job %s done: %lld tiles in %.2f s (%lld rendered twice), %.1f Mrays total\n", job_id.c_str(),
              (long long)final_status.tiles_total(), std::max(total, final_status.elapsed_seconds()),
              (long long)final_status.tiles_rendered_twice(), double(final_status.rays()) / 1e6);
  return 0;
}

// ---------------------------------------------------------------------------------------------

struct SubmitArgs {
  std::string scene, output, coordinator, frames, name;
  SecurityFlags security;
  ImageOptions image;
  int tile = 32;
  int priority = 0;
  bool detach = false;
  bool quiet = false;
  bool error_channels = false;
  double preview_every = 0;
  color::OutputOptions color;
};

void upload_if_missing(FarmClient& client, const farm::BuiltBundle& b) {
  try {
    if (!upload_bundle_if_missing(client, b)) return;
  } catch (const std::runtime_error& e) {
    throw FarmError{kExitFailure, e.what()};
  }
  std::printf("uploaded scene bundle %s (%zu files, %zu bytes)\n", b.sha256.substr(0, 12).c_str(), b.files,
              b.bytes.size());
}

int run_submit(const SubmitArgs& a) {
  // Validate locally first: the same message as `tessera render` for a bad scene.
  Scene scene;
  ImageOverrides o;
  try {
    scene = load_scene_with(a.scene, a.image, &o);
  } catch (const SceneError& e) {
    throw FarmError{kExitBadInput, e.what()};
  }
  int first = 0, last = scene.frame_count() - 1;
  if (!a.frames.empty()) {
    const auto dash = a.frames.find('-');
    try {
      first = std::stoi(a.frames.substr(0, dash));
      last = dash == std::string::npos ? first : std::stoi(a.frames.substr(dash + 1));
    } catch (const std::exception&) {
      throw FarmError{kExitBadInput, "--frames: expected A or A-B, got '" + a.frames + "'"};
    }
    if (first < 0 || last >= scene.frame_count() || first > last) {
      throw FarmError{kExitBadInput, "--frames " + a.frames + ": the scene has frames 0-" +
                                         std::to_string(scene.frame_count() - 1)};
    }
  }
  if (!a.detach) check_output_writable(a.output, first);

  FarmClient client = connect(a.coordinator, a.security);
  farm::BuiltBundle bundle;
  try {
    bundle = farm::make_bundle(a.scene, scene.dependencies);
  } catch (const farm::BundleError& e) {
    throw FarmError{kExitBadInput, e.what()};
  }
  upload_if_missing(client, bundle);

  v1::SubmitJobRequest req;
  req.set_bundle_sha256(bundle.sha256);
  farm::to_proto(o, req.mutable_overrides());
  // The coordinator and workers read the bundle's glTF exactly so (checked by load_scene_with).
  farm::to_proto(a.image.gltf_options(), req.mutable_overrides());
  req.set_first_frame(first);
  req.set_last_frame(last);
  req.set_tile_size(a.tile);
  req.set_priority(a.priority);
  req.set_name(a.name.empty() ? fs::path(a.scene).filename().string() : a.name);
  v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().SubmitJob(ctx.get(), req, &st);
  if (!s.ok()) {
    throw FarmError{s.error_code() == grpc::StatusCode::INVALID_ARGUMENT ? kExitBadInput : kExitFailure,
                    client.describe(s, "submitting the job")};
  }
  std::printf("job %s submitted to %s: frames %d-%d, %dx%d, %s, %lld tiles\n", st.job_id().c_str(),
              client.address().c_str(), st.first_frame(), st.last_frame(), st.width(), st.height(),
              describe_sampling(st).c_str(), (long long)st.tiles_total());
  std::fflush(stdout);
  if (a.detach) {
    std::printf("detached; get the frames with: tessera watch %s -o %s\n", st.job_id().c_str(),
                a.output.empty() ? "OUT_####.exr" : a.output.c_str());
    return 0;
  }
  return watch_job(client, st.job_id(), {a.output, req.name(), a.quiet, a.color, a.error_channels, a.preview_every});
}

struct JobArgs {
  std::string coordinator, job, output;
  SecurityFlags security;
  bool json = false, quiet = false;
  bool error_channels = false;
  double preview_every = 0;
  color::OutputOptions color;
  int priority = 0;  // `tessera priority`
};

int run_watch(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::GetJobRequest req;
  req.set_job_id(a.job);
  v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().GetJob(ctx.get(), req, &st);
  if (!s.ok()) {
    throw job_error(client, s, "looking up job " + a.job);
  }
  if (!a.output.empty()) check_output_writable(a.output, st.first_frame());
  return watch_job(client, a.job, {a.output, st.name(), a.quiet, a.color, a.error_channels, a.preview_every});
}

nlohmann::json job_json(const v1::JobStatus& j) {
  return {{"job_id", j.job_id()},
          {"name", j.name()},
          {"state", state_name(j.state())},
          {"priority", j.priority()},
          {"first_frame", j.first_frame()},
          {"last_frame", j.last_frame()},
          {"width", j.width()},
          {"height", j.height()},
          {"spp", j.spp()},
          {"target_rmse", j.overrides().has_target_rmse() ? nlohmann::json(j.overrides().target_rmse()) : nlohmann::json(nullptr)},
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
           std::vector<std::string>(j.blocklisted_workers().begin(), j.blocklisted_workers().end())}};
}

void print_job(const v1::JobStatus& j) {
  const std::string frames = std::to_string(j.first_frame()) + "-" + std::to_string(j.last_frame());
  const std::string size = std::to_string(j.width()) + "x" + std::to_string(j.height());
  const std::string tiles = std::to_string(j.tiles_done()) + "/" + std::to_string(j.tiles_total());
  std::printf("%-14s %-10s %5d  %-11s %-11s %6d  %-15s %9s  %s\n", j.job_id().c_str(), state_name(j.state()),
              j.priority(), frames.c_str(), size.c_str(), j.spp(), tiles.c_str(),
              fmt_duration(j.elapsed_seconds()).c_str(), j.name().c_str());
}

int run_status(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  std::vector<v1::JobStatus> jobs;
  if (!a.job.empty()) {
    v1::GetJobRequest req;
    req.set_job_id(a.job);
    v1::JobStatus st;
    auto ctx = client.context();
    grpc::Status s = client.stub().GetJob(ctx.get(), req, &st);
    if (!s.ok()) {
      throw job_error(client, s, "looking up job " + a.job);
    }
    jobs.push_back(st);
  } else {
    v1::ListJobsResponse resp;
    auto ctx = client.context();
    grpc::Status s = client.stub().ListJobs(ctx.get(), {}, &resp);
    if (!s.ok()) throw FarmError{kExitFailure, client.describe(s, "listing jobs")};
    jobs.assign(resp.jobs().begin(), resp.jobs().end());
  }
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
  return 0;
}

int run_cancel(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::CancelJobRequest req;
  req.set_job_id(a.job);
  v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().CancelJob(ctx.get(), req, &st);
  if (!s.ok()) {
    throw job_error(client, s, "cancelling job " + a.job);
  }
  std::printf("job %s: %s (%lld/%lld tiles were done)\n", st.job_id().c_str(), state_name(st.state()),
              (long long)st.tiles_done(), (long long)st.tiles_total());
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

int run_workers(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::ListWorkersResponse resp;
  auto ctx = client.context();
  grpc::Status s = client.stub().ListWorkers(ctx.get(), {}, &resp);
  if (!s.ok()) throw FarmError{kExitFailure, client.describe(s, "listing workers")};
  if (a.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& w : resp.workers()) {
      out.push_back({{"worker_id", w.worker_id()}, {"name", w.name()}, {"peer", w.peer()},
                     {"threads", w.threads()}, {"embree_isa", w.embree_isa()},
                     {"tiles_in_flight", w.tiles_in_flight()}, {"tiles_done", w.tiles_done()}, {"rays", w.rays()},
                     {"render_seconds", w.render_seconds()}, {"connected_seconds", w.connected_seconds()},
                     {"since_heartbeat_seconds", w.since_heartbeat_seconds()}});
    }
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  if (resp.workers().empty()) {
    std::printf("no workers connected to %s\n", client.address().c_str());
    return 0;
  }
  std::printf("%-4s %-20s %-22s %7s %-20s %9s %8s %8s %8s\n", "ID", "NAME", "PEER", "THREADS", "ISA", "IN-FLIGHT",
              "TILES", "MRAYS/S", "UP");
  for (const auto& w : resp.workers()) {
    const double mrays = w.render_seconds() > 0 ? double(w.rays()) / w.render_seconds() * w.threads() / 1e6 : 0;
    std::printf("%-4s %-20s %-22s %7d %-20s %9d %8lld %8.1f %8s\n", w.worker_id().c_str(), w.name().c_str(),
                w.peer().c_str(), w.threads(), w.embree_isa().c_str(), w.tiles_in_flight(),
                (long long)w.tiles_done(), mrays, fmt_duration(w.connected_seconds()).c_str());
  }
  return 0;
}

int run_rayservers(const JobArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  v1::ListRayServersResponse resp;
  auto ctx = client.context();
  grpc::Status s = client.stub().ListRayServers(ctx.get(), {}, &resp);
  if (!s.ok()) throw FarmError{kExitFailure, client.describe(s, "listing ray servers")};
  if (a.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& r : resp.servers()) {
      const v1::RayServerDescription& d = r.server();
      out.push_back({{"server_id", d.server_id()}, {"address", d.address()}, {"threads", d.threads()},
                     {"embree_isa", d.embree_isa()}, {"max_batch_rays", d.max_batch_rays()}, {"tls", d.tls()},
                     {"client_token", d.client_token()}, {"version", d.version()}, {"requests", d.requests()},
                     {"rays", d.rays()}, {"rays_in_flight", d.rays_in_flight()}, {"peer", r.peer()},
                     {"up_seconds", r.up_seconds()}, {"since_announcement_seconds", r.since_announcement_seconds()},
                     {"expiry_ms", r.expiry_ms()}});
    }
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  if (resp.servers().empty()) {
    std::printf("no ray servers announced to %s (start one with: tessera-rays --coordinator %s)\n",
                client.address().c_str(), client.address().c_str());
    return 0;
  }
  std::printf("%-16s %-22s %7s %-20s %-9s %10s %12s %9s %8s %6s\n", "ID", "ADDRESS", "THREADS", "ISA", "SECURITY",
              "REQUESTS", "RAYS", "IN-FLIGHT", "UP", "SEEN");
  for (const auto& r : resp.servers()) {
    const v1::RayServerDescription& d = r.server();
    const std::string security = std::string(d.tls() ? "tls" : "plain") + (d.client_token() ? "+tok" : "");
    std::printf("%-16s %-22s %7d %-20s %-9s %10llu %12llu %9llu %8s %5.1fs\n", d.server_id().c_str(),
                d.address().c_str(), d.threads(), d.embree_isa().c_str(), security.c_str(),
                (unsigned long long)d.requests(), (unsigned long long)d.rays(), (unsigned long long)d.rays_in_flight(),
                fmt_duration(r.up_seconds()).c_str(), r.since_announcement_seconds());
  }
  return 0;
}

// Runs a command, turning FarmError into a message and an exit code for CLI11.
template <class F>
void guarded(const char* name, F f) {
  int rc = 0;
  try {
    rc = f();
  } catch (const FarmError& e) {
    std::cerr << "tessera " << name << ": " << e.message << "\n";
    rc = e.code;
  }
  if (rc != 0) throw CLI::RuntimeError(rc);
}

void add_coordinator_option(CLI::App* cmd, std::string* target, SecurityFlags* security) {
  cmd->add_option("--coordinator", *target,
                  "Coordinator HOST:PORT (default: $TESSERA_COORDINATOR, else 127.0.0.1:7878)");
  cmd->add_option("--token-file", security->token_file, "File holding the client token (else $TESSERA_CLIENT_TOKEN)")
      ->group("Security");
  cmd->add_option("--tls-ca", security->tls_ca, "PEM CA certificate of the coordinator: connect with TLS "
                                                "(else $TESSERA_TLS_CA)")->group("Security");
  cmd->add_option("--tls-cert", security->tls_cert, "PEM client certificate, for a coordinator that asks for one")
      ->group("Security");
  cmd->add_option("--tls-key", security->tls_key, "PEM private key of --tls-cert")->group("Security");
}

void add_frame_output_options(CLI::App* cmd, bool* error_channels, double* preview_every) {
  cmd->add_flag("--error-channels", *error_channels,
                "Add per-pixel layers to each EXR: error.Y (estimated RMSE of the pixel) and spp.Y (its samples)");
  cmd->add_option("--preview-every", *preview_every,
                  "Every this many seconds, write each frame in progress beside its output as NAME.preview.EXT "
                  "(missing tiles black; removed when the frame is written)")
      ->check(CLI::Range(0.1, 86400.0));
}

}  // namespace

void register_farm_commands(CLI::App& app) {
  {
    auto a = std::make_shared<SubmitArgs>();
    CLI::App* cmd = app.add_subcommand("submit", "Render a scene on the farm and write its frames");
    cmd->add_option("scene", a->scene, "Scene file: JSON, or glTF 2.0 (.gltf/.glb); see docs/scene-format.md")->required();
    cmd->add_option("-o,--output", a->output, "Output EXR path; '#' runs become the frame number");
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->add_option("--frames", a->frames, "Frames A-B (inclusive) or A (default: all)");
    add_image_options(*cmd, a->image);
    cmd->add_option("--tile", a->tile, "Tile size in pixels (does not change the image)")->check(CLI::Range(4, 256));
    cmd->add_option("--priority", a->priority, "Higher runs first (default 0)");
    cmd->add_option("--name", a->name, "Job name (default: the scene file name)");
    cmd->add_flag("--detach", a->detach, "Submit and return; fetch the frames later with `tessera watch`");
    cmd->add_flag("-q,--quiet", a->quiet, "No progress display");
    add_frame_output_options(cmd, &a->error_channels, &a->preview_every);
    add_output_options(*cmd, a->color);  // -o frame_####.png etc.: see `tessera convert`
    cmd->callback([a] {
      guarded("submit", [&] {
        if (a->output.empty() && !a->detach) throw FarmError{kExitBadInput, "-o/--output is required (or --detach)"};
        return run_submit(*a);
      });
    });
  }
  {
    auto a = std::make_shared<JobArgs>();
    CLI::App* cmd = app.add_subcommand("watch", "Re-attach to a job: progress, and its frames with -o");
    cmd->add_option("job", a->job, "Job id")->required();
    cmd->add_option("-o,--output", a->output, "Write frames here ('#' runs become the frame number)");
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->add_flag("-q,--quiet", a->quiet, "No progress display");
    add_frame_output_options(cmd, &a->error_channels, &a->preview_every);
    add_output_options(*cmd, a->color);
    cmd->callback([a] { guarded("watch", [&] { return run_watch(*a); }); });
  }
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
  {
    auto a = std::make_shared<JobArgs>();
    CLI::App* cmd = app.add_subcommand("workers", "List the workers connected to the coordinator");
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->add_flag("--json", a->json, "Machine-readable output");
    cmd->callback([a] { guarded("workers", [&] { return run_workers(*a); }); });
  }
  {
    auto a = std::make_shared<JobArgs>();
    CLI::App* cmd = app.add_subcommand(
        "rayservers", "List the ray servers (tessera-rays) announced to the coordinator, which `tessera rays` picks from");
    add_coordinator_option(cmd, &a->coordinator, &a->security);
    cmd->add_flag("--json", a->json, "Machine-readable output");
    cmd->callback([a] { guarded("rayservers", [&] { return run_rayservers(*a); }); });
  }
}

}  // namespace tessera::cli

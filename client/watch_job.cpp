// SPDX-License-Identifier: Apache-2.0
#include "watch_job.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "farm_command.h"
#include "farm_frames.h"
#include "image/output_path.h"
#include "interrupt.h"
#include "job_text.h"
#include "progress_line.h"
#include "sample_report.h"
#include "watch_reattach.h"

namespace tessera::cli {

namespace v1 = tessera::v1;
namespace fs = std::filesystem;

namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The progress display's error: the estimate over the pixels received so far, and the target.
std::string progress_error(const FrameAssembler& frames) {
  if (frames.tiles_received() == 0) return {};
  char buf[96];
  if (frames.settings().adaptive()) {
    std::snprintf(buf, sizeof buf, "est. RMSE %.3g (%s %.3g)", frames.running_estimated_rmse(),
                  frames.settings().frame_target() ? "target" : "block bound", frames.settings().target());
  } else {
    std::snprintf(buf, sizeof buf, "est. RMSE %.3g", frames.running_estimated_rmse());
  }
  return buf;
}

// One watch of one job, across the streams it takes when the coordinator goes away.
class JobWatch {
 public:
  JobWatch(FarmClient& client, const std::string& job_id, const WatchOptions& o)
      : client_(client), job_id_(job_id), o_(o) {}

  int run();

 private:
  // Reads one WatchJob stream to its end; `ended`: it delivered the job's final state.
  grpc::Status read_stream(bool* ended);
  void on_status(const v1::JobStatus& st, bool* ended);
  void print_header(const v1::JobStatus& st) const;
  void on_tile(const v1::TileData& tile);
  void on_frame_done(int f);
  void write_frame(int f);
  grpc::Status acknowledge(int f);
  int finish();

  FarmClient& client_;
  const std::string& job_id_;
  const WatchOptions& o_;
  std::optional<FrameAssembler> frames_;
  std::optional<Progress> progress_;
  v1::JobStatus final_status_;
  std::set<int> delivered_before_;  // frames acknowledged by a client (maybe this one)
  ReattachPolicy reattach_;
  double total_start_ = now_s();
  double last_preview_ = now_s();
};

int JobWatch::run() {
  while (true) {
    bool ended = false;
    const grpc::Status s = read_stream(&ended);
    switch (reattach_.after_stream(s.error_code(), ended, frames_.has_value())) {
      case StreamEnd::kFinished:
        return finish();
      case StreamEnd::kBadInput:
        if (o_.refused) *o_.refused = s.error_code();
        throw CommandError{kExitBadInput, s.error_message()};
      case StreamEnd::kReattach:
        // Lost the coordinator mid-job: re-attach (finished tiles are kept for us).
        spdlog::warn("lost the watch stream ({}); re-attaching", s.error_message());
        std::this_thread::sleep_for(ReattachPolicy::kPause);
        // Back as soon as the coordinator listens again, waiting for it at most reattach_.wait().
        client_.wait_for_coordinator(reattach_.wait());
        break;
      case StreamEnd::kGiveUp:
        if (o_.refused) *o_.refused = s.error_code();
        throw CommandError{kExitFailure, client_.describe(s, "watching job " + job_id_)};
    }
  }
}

grpc::Status JobWatch::read_stream(bool* ended) {
  // Long-lived stream: no short deadline (a job may take days); keepalive pings on the
  // channel detect a dead coordinator, and a lost stream is re-attached by run().
  auto ctx = FarmClient::context(std::chrono::hours(24 * 30));
  v1::WatchJobRequest req;
  req.set_job_id(job_id_);
  req.set_tile_batches(true);
  req.set_deliver_frames(!o_.output.empty());
  auto stream = client_.stub().WatchJob(ctx.get(), req);
  v1::WatchJobEvent ev;
  v1::TileData tile;
  while (stream->Read(&ev)) {
    if (ev.has_status()) {
      on_status(ev.status(), ended);
    } else if (ev.has_tile()) {
      on_tile(ev.tile());
    } else if (ev.has_tiles()) {
      for (const std::string& bytes : ev.tiles().tiles()) {
        if (!tile.ParseFromString(bytes)) {
          spdlog::warn("ignored a tile: not a TileData message ({} bytes)", bytes.size());
          continue;
        }
        on_tile(tile);
      }
    } else if (ev.event_case() == v1::WatchJobEvent::kFrameDone) {
      on_frame_done(ev.frame_done());
    }
  }
  return stream->Finish();
}

void JobWatch::on_status(const v1::JobStatus& st, bool* ended) {
  reattach_.attached();
  if (!frames_) {
    frames_.emplace(st);
    if (!o_.quiet) print_header(st);
    // Unacknowledged finished tiles are re-sent on this stream: count from the frames
    // already delivered to an earlier client.
    progress_.emplace(st.tiles_total(), int64_t(st.frames_acknowledged_size()) * st.tiles_per_frame());
  }
  delivered_before_.insert(st.frames_acknowledged().begin(), st.frames_acknowledged().end());
  if (is_final(st.state())) {
    *ended = true;
    final_status_ = st;
  }
}

void JobWatch::print_header(const v1::JobStatus& st) const {
  std::printf("job %s: %s, frames %d-%d, %dx%d, %s, %lld tiles (%lld done)\n", st.job_id().c_str(),
              state_name(st.state()), st.first_frame(), st.last_frame(), st.width(), st.height(),
              describe_sampling(st).c_str(), (long long)st.tiles_total(), (long long)st.tiles_done());
  for (int f : st.frames_acknowledged()) {
    std::printf("frame %d was already delivered to an earlier client\n", f);
  }
  std::fflush(stdout);
}

void JobWatch::on_tile(const v1::TileData& tile) {
  if (const std::string err = frames_->add(tile); !err.empty()) spdlog::warn("ignored a tile: {}", err);
  if (!o_.quiet) progress_->update(frames_->tiles_received(), frames_->rays_received(), progress_error(*frames_));
  if (o_.preview_every > 0 && !o_.output.empty() && now_s() - last_preview_ >= o_.preview_every) {
    last_preview_ = now_s();
    try {
      const OutputWrite whole;
      frames_->write_previews(o_.output, o_.color);
    } catch (const std::exception& e) {
      spdlog::warn("cannot write a preview: {}", e.what());  // the frames themselves still come
    }
  }
}

void JobWatch::on_frame_done(int f) {
  if (!o_.output.empty() && frames_->written(f)) {
    // Re-sent after a coordinator restart lost our acknowledgement: acknowledge it again so
    // the coordinator can release the frame.
    acknowledge(f);
    return;
  }
  if (o_.output.empty()) return;
  if (!frames_->complete(f)) {
    // Never write or acknowledge a frame with holes: the coordinator keeps its tiles.
    spdlog::error("frame {} reported done but {}: not written, not acknowledged", f, frames_->missing_tiles(f));
    return;
  }
  write_frame(f);
  grpc::Status s = acknowledge(f);
  if (!s.ok()) spdlog::warn("{}", client_.describe(s, "acknowledging frame " + std::to_string(f)));
}

void JobWatch::write_frame(int f) {
  FrameReport rep;
  try {
    const OutputWrite whole;
    rep = frames_->write(f, o_.output, o_.scene_name, o_.color, o_.error_channels);
  } catch (const std::exception& e) {
    throw CommandError{kExitFailure, std::string("cannot write frame ") + std::to_string(f) + ": " + e.what()};
  }
  if (!o_.quiet) progress_->clear_line();
  const double secs = rep.wall_seconds > 0.05 ? rep.wall_seconds : rep.tile_seconds;
  std::printf("%s: frame %d: %.3f s, %.2f Mrays/s, %s, %zu worker(s)\n", rep.path.c_str(), f, secs,
              secs > 0 ? double(rep.rays) / secs / 1e6 : 0.0,
              describe_samples(rep.samples, frames_->settings()).c_str(), rep.workers.size());
  std::fflush(stdout);
  if (const std::string w = target_warning(rep.samples, frames_->settings()); !w.empty()) {
    spdlog::warn("frame {}: {}", f, w);
  }
}

grpc::Status JobWatch::acknowledge(int f) {
  v1::AckFrameRequest ack;
  ack.set_job_id(job_id_);
  ack.set_frame(f);
  v1::AckFrameResponse ack_resp;
  auto actx = client_.context();
  return client_.stub().AckFrame(actx.get(), ack, &ack_resp);
}

int JobWatch::finish() {
  if (!o_.quiet) {
    progress_->update(frames_->tiles_received(), frames_->rays_received(), progress_error(*frames_), true);
    progress_->clear_line();
  }
  const double total = now_s() - total_start_;
  if (final_status_.state() == v1::JOB_STATE_FAILED) {
    throw CommandError{kExitFailure, "job " + job_id_ + " failed: " + final_status_.error()};
  }
  if (final_status_.state() == v1::JOB_STATE_CANCELLED) {
    std::printf("job %s was cancelled\n", job_id_.c_str());
    return kExitCancelled;
  }
  // "Done" is only success when every frame reached a file (here or through an earlier client).
  if (!o_.output.empty()) {
    if (const std::string lost = frames_->frames_not_written(delivered_before_); !lost.empty()) {
      throw CommandError{kExitFailure, "job " + job_id_ + " is done on the coordinator, but not every frame arrived "
                                       "complete, so these were not written: " + lost};
    }
  }
  std::printf("job %s done: %lld tiles in %.2f s (%lld rendered twice), %.1f Mrays total\n", job_id_.c_str(),
              (long long)final_status_.tiles_total(), std::max(total, final_status_.elapsed_seconds()),
              (long long)final_status_.tiles_rendered_twice(), double(final_status_.rays()) / 1e6);
  return 0;
}

}  // namespace

void add_frame_output_options(CLI::App* cmd, bool* error_channels, double* preview_every) {
  cmd->add_flag("--error-channels", *error_channels,
                "Add per-pixel layers to each EXR: error.Y (estimated RMSE of the pixel) and spp.Y (its samples)");
  cmd->add_option("--preview-every", *preview_every,
                  "Every this many seconds, write each frame in progress beside its output as NAME.preview.EXT "
                  "(missing tiles black; removed when the frame is written)")
      ->check(CLI::Range(0.1, 86400.0));
}

void check_output_writable(const std::string& pattern, int frame) {
  const fs::path out = frame_output_path(pattern, frame);
  fs::path dir = out.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    throw CommandError{kExitFailure,
                       "output '" + pattern + "' is not writable: cannot create " + dir.string() + ": " + ec.message()};
  }
  const fs::path probe = dir / (".tessera-write-test-" + std::to_string(getpid()));
  {
    std::ofstream f(probe);
    if (!f) {
      throw CommandError{kExitFailure,
                         "output '" + pattern + "' is not writable: cannot create files in " + dir.string()};
    }
  }
  fs::remove(probe, ec);
}

int watch_job(FarmClient& client, const std::string& job_id, const WatchOptions& o) {
  if (!o.interrupt_notice) return JobWatch(client, job_id, o).run();
  say_on_interrupt(interrupt_notice(job_id, client.address(), o.output));
  struct Ended {
    ~Ended() { say_on_interrupt(""); }  // a watch that has ended has nothing to say
  } ended;
  return JobWatch(client, job_id, o).run();
}

}  // namespace tessera::cli

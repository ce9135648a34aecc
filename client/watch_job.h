// SPDX-License-Identifier: Apache-2.0
// Watching a job: receives its tiles over a WatchJob stream, writes each frame when complete,
// acknowledges it (so the coordinator can release its tiles) and re-attaches after losing the
// coordinator (watch_reattach.h). `tessera watch` and `tessera submit` without --detach both end
// here.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "color/output_options.h"
#include "farm_client.h"

namespace tessera::cli {

struct WatchOptions {
  std::string output;        // empty: progress only, frames are neither written nor acknowledged
  std::string scene_name;
  bool quiet = false;
  color::OutputOptions color;  // tone mapping / format when the output is not a float EXR
  bool error_channels = false;  // error.Y and spp.Y layers in each EXR
  double preview_every = 0;     // seconds between previews of frames in progress; 0: none
  // What an interrupt says: how to come back to this job (false: the caller says something else,
  // as `tessera collect` does for its many jobs).
  bool interrupt_notice = true;
  // When the watch gives up on a refusal, the refusal's code (e.g. PERMISSION_DENIED: another
  // identity's job) is stored here if set, for callers that act on it (`tessera collect`).
  grpc::StatusCode* refused = nullptr;
};

// Adds --error-channels and --preview-every, the frame output flags of `submit` and `watch`.
void add_frame_output_options(CLI::App* cmd, bool* error_channels, double* preview_every);

// Fails early (CommandError), before anything is submitted or watched, if the output cannot be
// written: creates the folder of `frame`'s file and a probe file in it.
void check_output_writable(const std::string& pattern, int frame);

// Watches the job to its end; returns the exit code (0 done, kExitCancelled) or throws CommandError.
// With an output the watch is a deliverer (WatchJobRequest.deliver_frames): it is sent the frames
// the coordinator leases to it, writes and acknowledges them, and ends once every finished frame of
// the ended job is delivered, by it or by another client.
int watch_job(FarmClient& client, const std::string& job_id, const WatchOptions& o);

}  // namespace tessera::cli

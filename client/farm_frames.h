// SPDX-License-Identifier: Apache-2.0
// Assembles a job's finished tiles into frames on the client and writes each complete frame as
// a float OpenEXR, laid out by the same FrameAssembly as `tessera render` uses, so the files are
// bit-identical to an in-process render.
#pragma once

#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "image/exr_io.h"
#include "image/image.h"
#include "render/adaptive.h"
#include "tessera/v1/client_service.pb.h"
#include "tile/frame_assembly.h"

#include "color/output_options.h"

namespace tessera::cli {

struct FrameReport {
  int frame = 0;
  std::string path;
  double wall_seconds = 0;    // first to last tile arriving at this client
  double tile_seconds = 0;    // sum of the tiles' render times (thread-seconds)
  uint64_t rays = 0;
  SampleSummary samples;      // the estimated RMSE, spp range, target not reached
  std::set<std::string> workers;
};

// The job's image settings as the coordinator resolved them (its overrides carry the target
// error in effect, also when it came from the scene file).
ImageSettings job_image_settings(const tessera::v1::JobStatus& job);

// Where the preview of a frame in progress goes: the frame's path with ".preview" before the
// extension (out/frame_0003.exr -> out/frame_0003.preview.exr).
std::string preview_path(const std::string& frame_path);

class FrameAssembler {
 public:
  explicit FrameAssembler(const tessera::v1::JobStatus& job);

  // Adds a tile: "" when it is placed, or ignored (a second copy, or a tile of a frame already
  // written); else why it does not belong, and it is not placed.
  std::string add(const tessera::v1::TileData& tile);
  bool complete(int frame) const;
  // The frame's tiles not received yet, e.g. "tiles 3, 17 missing (58 of 60 received)".
  std::string missing_tiles(int frame) const;
  // The job's frames that were neither written here nor in `delivered_before` (acknowledged by
  // an earlier client), each with its missing tiles; "" when every frame is accounted for. A job
  // the coordinator calls done must leave this empty: otherwise a frame is lost, and the client
  // must say so rather than exit 0.
  std::string frames_not_written(const std::set<int>& delivered_before) const;
  bool written(int frame) const { return written_.count(frame) > 0; }
  // Writes the frame to frame_output_path(pattern, frame): a float EXR with the job's
  // attributes, or (other extensions / --format) tone-mapped and quantized by `color`.
  // Throws ExrError / ColorError naming the path.
  // `error_channels` adds the error.Y and spp.Y layers (float EXR output only).
  FrameReport write(int frame, const std::string& pattern, const std::string& scene_name,
                    const color::OutputOptions& color, bool error_channels = false);
  // Writes every frame that has tiles but is not complete to its preview_path (missing tiles
  // black; attribute tessera:tilesDone); returns how many were written.
  int write_previews(const std::string& pattern, const color::OutputOptions& color);
  uint64_t rays_received() const { return rays_; }
  int64_t tiles_received() const { return tiles_; }
  // The estimated RMSE over every pixel received so far (the error the progress display shows).
  double running_estimated_rmse() const {
    return pixels_ > 0 ? std::sqrt(variance_sum_ / double(pixels_)) : 0.0;
  }
  const ImageSettings& settings() const { return settings_; }

 private:
  struct Frame {
    FrameAssembly pixels;
    double first = 0, last = 0;  // arrival times
    double tile_seconds = 0;
    uint64_t rays = 0;
    std::set<std::string> workers;
  };
  tessera::v1::JobStatus job_;
  TileGrid grid_;  // how the coordinator cut each frame (tile index -> rectangle)
  ImageSettings settings_;
  std::map<int, Frame> frames_;
  std::set<int> written_;
  uint64_t rays_ = 0;
  int64_t tiles_ = 0;
  double variance_sum_ = 0;
  int64_t pixels_ = 0;
};

}  // namespace tessera::cli

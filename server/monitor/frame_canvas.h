// SPDX-License-Identifier: Apache-2.0
// One frame of a job as the monitor sees it converge: the pixels of the tiles finished so far
// (missing tiles black), which worker rendered each tile, and the frame's render statistics.
// The preview PNG is tone-mapped here, in the coordinator, the same way `tessera convert` makes
// an 8-bit PNG of a finished frame (color::tonemap_to_rgb8).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "color/tonemap.h"
#include "tessera/v1/common.pb.h"
#include "tile/frame_assembly.h"

namespace tessera::server {

// What the monitor reports of a frame; kept for every frame it saw tiles of (no pixels).
struct FrameStats {
  int tiles = 0;
  double first_seen = 0, last_seen = 0;  // seconds (steady clock) when its first / last tile arrived
  double tile_seconds = 0;               // sum of the tiles' render times (worker thread-seconds)
  double variance_sum = 0;               // over its pixels: sqrt(variance_sum / pixels) is the est. RMSE
  int64_t pixels = 0;
  double estimated_rmse() const;
};

class FrameCanvas {
 public:
  FrameCanvas(int width, int height, int tile_size);
  // Places the tile's pixels. Returns "" or why the tile does not fit this frame (outside it,
  // wrong sizes). A tile already placed is ignored (the first copy of a tile wins, as in the
  // scheduler).
  std::string add(const tessera::v1::TileData& tile);
  bool has(int tile_index) const { return frame_.has(tile_index); }
  int tiles_done() const { return frame_.tiles_done(); }
  int tiles_x() const { return frame_.grid().columns(); }
  int tiles_y() const { return frame_.grid().rows(); }
  // For each tile (row-major): the index in workers() of the worker that rendered it, or -1.
  const std::vector<int>& worker_of() const { return worker_of_; }
  const std::vector<std::string>& workers() const { return workers_; }
  // The frame tone-mapped and encoded as an 8-bit sRGB PNG. Throws color::ColorError.
  std::string png(const color::ToneMapSettings& tonemap) const;

 private:
  FrameAssembly frame_;  // the colour only: the monitor shows no error layers
  std::vector<int> worker_of_;
  std::vector<std::string> workers_;
  std::map<std::string, int> worker_index_;
};

}  // namespace tessera::server

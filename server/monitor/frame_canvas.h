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
#include "image/image.h"
#include "tessera/v1/common.pb.h"

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
  bool has(int tile_index) const { return tile_index >= 0 && size_t(tile_index) < worker_of_.size() && worker_of_[size_t(tile_index)] >= 0; }
  int tiles_done() const { return tiles_done_; }
  int tiles_x() const { return tiles_x_; }
  int tiles_y() const { return tiles_y_; }
  // For each tile (row-major): the index in workers() of the worker that rendered it, or -1.
  const std::vector<int>& worker_of() const { return worker_of_; }
  const std::vector<std::string>& workers() const { return workers_; }
  // The frame tone-mapped and encoded as an 8-bit sRGB PNG. Throws color::ColorError.
  std::string png(const color::ToneMapSettings& tonemap) const;

 private:
  ImageRGB image_;
  int tile_size_;
  int tiles_x_, tiles_y_;
  int tiles_done_ = 0;
  std::vector<int> worker_of_;
  std::vector<std::string> workers_;
  std::map<std::string, int> worker_index_;
};

}  // namespace tessera::server

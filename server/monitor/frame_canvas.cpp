#include "frame_canvas.h"

#include <cmath>
#include <cstring>

#include "color/color_convert.h"
#include "color/png_io.h"

namespace tessera::server {

double FrameStats::estimated_rmse() const { return pixels > 0 ? std::sqrt(variance_sum / double(pixels)) : 0.0; }

FrameCanvas::FrameCanvas(int width, int height, int tile_size)
    : image_(width, height),
      tile_size_(tile_size),
      tiles_x_((width + tile_size - 1) / tile_size),
      tiles_y_((height + tile_size - 1) / tile_size),
      worker_of_(size_t(tiles_x_) * size_t(tiles_y_), -1) {}

std::string FrameCanvas::add(const tessera::v1::TileData& tile) {
  const int index = tile.tile_index();
  if (index < 0 || size_t(index) >= worker_of_.size()) return "tile " + std::to_string(index) + " is outside the frame";
  if (has(index)) return {};
  // The coordinator checked the tile against its lease before accepting it (Coordinator::
  // tile_result_locked); these checks only keep a bad record from reaching memory it does not own.
  const int x0 = (index % tiles_x_) * tile_size_, y0 = (index / tiles_x_) * tile_size_;
  const int w = tile.rect().width(), h = tile.rect().height();
  if (tile.rect().x0() != x0 || tile.rect().y0() != y0 || w <= 0 || h <= 0 || x0 + w > image_.width ||
      y0 + h > image_.height || tile.rgb().size() != size_t(w) * size_t(h) * 3 * sizeof(float)) {
    return "tile " + std::to_string(index) + " does not match its rectangle";
  }
  // Rows copied straight from the tile's little-endian float32 bytes (the farm's wire format,
  // proto/farm/codec.h): place_tile would need the renderer's library (Embree) in the coordinator.
  for (int y = 0; y < h; ++y) {
    std::memcpy(image_.at(x0, y0 + y), tile.rgb().data() + size_t(y) * size_t(w) * 3 * sizeof(float),
                size_t(w) * 3 * sizeof(float));
  }
  auto [it, inserted] = worker_index_.emplace(tile.worker(), int(workers_.size()));
  if (inserted) workers_.push_back(tile.worker());
  worker_of_[size_t(index)] = it->second;
  ++tiles_done_;
  return {};
}

std::string FrameCanvas::png(const color::ToneMapSettings& tonemap) const {
  return color::encode_png(color::tonemap_to_rgb8(image_, tonemap));
}

}  // namespace tessera::server

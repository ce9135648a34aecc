// SPDX-License-Identifier: Apache-2.0
#include "frame_canvas.h"

#include <cmath>

#include "color/color_convert.h"
#include "color/png_io.h"
#include "farm/tile_codec.h"

namespace tessera::server {

double FrameStats::estimated_rmse() const { return pixels > 0 ? std::sqrt(variance_sum / double(pixels)) : 0.0; }

FrameCanvas::FrameCanvas(int width, int height, int tile_size)
    : frame_(TileGrid(width, height, tile_size), FrameAssembly::Layers::kColour),
      worker_of_(size_t(frame_.grid().count()), -1) {}

std::string FrameCanvas::add(const tessera::v1::TileData& tile) {
  const int index = tile.tile_index();
  if (!frame_.grid().contains(index)) return "tile " + std::to_string(index) + " is outside the frame";
  if (has(index)) return {};
  // The coordinator checked the tile against its lease before accepting it (farm::validate_tile);
  // these checks only keep a bad record from reaching memory it does not own.
  TileResult pixels;
  if (!farm::decode_tile(tile, &pixels).empty() || !frame_.place(index, pixels).empty()) {
    return "tile " + std::to_string(index) + " does not match its rectangle";
  }
  auto [it, inserted] = worker_index_.emplace(tile.worker(), int(workers_.size()));
  if (inserted) workers_.push_back(tile.worker());
  worker_of_[size_t(index)] = it->second;
  return {};
}

std::string FrameCanvas::png(const color::ToneMapSettings& tonemap) const {
  return color::encode_png(color::tonemap_to_rgb8(frame_.image(), tonemap));
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "tile/frame_assembly.h"

#include <algorithm>

namespace tessera {

FrameAssembly::FrameAssembly(const TileGrid& grid, Layers layers)
    : grid_(grid), image_(grid.width(), grid.height()), in_(size_t(grid.count()), false) {
  if (layers == Layers::kEstimates) {
    variance_.assign(image_.pixel_count(), 0.0f);
    spp_.assign(image_.pixel_count(), 0);
  }
}

std::string FrameAssembly::place(int index, const TileResult& tile, bool* placed) {
  if (placed) *placed = false;
  if (!grid_.contains(index)) {
    return "tile " + std::to_string(index) + " is outside the frame's " + std::to_string(grid_.count()) + " tiles";
  }
  const TileRect& r = tile.rect;
  if (!(r == grid_.rect(index))) return "tile " + std::to_string(index) + " does not match its rectangle";
  const size_t px = size_t(r.pixels());
  if (tile.rgb.size() != 3 * px || (!variance_.empty() && tile.variance.size() != px) ||
      (!tile.spp.empty() && tile.spp.size() != px)) {
    return "tile " + std::to_string(index) + " has pixel arrays of the wrong size";
  }
  if (in_[size_t(index)]) return {};
  for (int y = 0; y < r.height; ++y) {
    const size_t src = size_t(y) * size_t(r.width);
    const size_t dst = size_t(r.y0 + y) * size_t(image_.width) + size_t(r.x0);
    std::copy_n(&tile.rgb[3 * src], 3 * size_t(r.width), image_.at(r.x0, r.y0 + y));
    if (!variance_.empty()) std::copy_n(&tile.variance[src], size_t(r.width), &variance_[dst]);
    // Tiles without sample counts leave the layer as it is (the caller fills them in first).
    if (!spp_.empty() && !tile.spp.empty()) std::copy_n(&tile.spp[src], size_t(r.width), &spp_[dst]);
  }
  in_[size_t(index)] = true;
  ++tiles_done_;
  if (placed) *placed = true;
  return {};
}

}  // namespace tessera

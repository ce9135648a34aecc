// SPDX-License-Identifier: Apache-2.0
#include "tile/tile_grid.h"

#include <algorithm>

namespace tessera {

TileGrid::TileGrid(int width, int height, int size)
    : width_(width),
      height_(height),
      size_(std::max(1, size)),
      columns_(width > 0 ? (width + size_ - 1) / size_ : 0),
      rows_(height > 0 ? (height + size_ - 1) / size_ : 0) {}

TileRect TileGrid::rect(int index) const {
  TileRect r;
  r.x0 = (index % columns_) * size_;
  r.y0 = (index / columns_) * size_;
  r.width = std::min(size_, width_ - r.x0);
  r.height = std::min(size_, height_ - r.y0);
  return r;
}

std::vector<TileRect> TileGrid::rects() const {
  std::vector<TileRect> out;
  out.reserve(size_t(count()));
  for (int i = 0; i < count(); ++i) out.push_back(rect(i));
  return out;
}

}  // namespace tessera

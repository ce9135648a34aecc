// SPDX-License-Identifier: Apache-2.0
// How a frame is cut into tiles: squares of `size` pixels in row-major order from the top-left,
// the last column and row cut short where the frame's size is not a multiple of `size`. Tile
// indices on the wire, in the database and in the monitor all count in this order, so it is
// written once, here.
#pragma once

#include <vector>

#include "tile/tile_rect.h"

namespace tessera {

class TileGrid {
 public:
  TileGrid() = default;
  // A size below 1 is taken as 1 (a damaged record must not divide by zero).
  TileGrid(int width, int height, int size);

  int width() const { return width_; }
  int height() const { return height_; }
  int size() const { return size_; }
  int columns() const { return columns_; }
  int rows() const { return rows_; }
  int count() const { return columns_ * rows_; }
  bool contains(int index) const { return index >= 0 && index < count(); }
  // The rectangle of tile `index` (0 <= index < count()).
  TileRect rect(int index) const;
  // Every tile's rectangle, in index order.
  std::vector<TileRect> rects() const;

 private:
  int width_ = 0, height_ = 0, size_ = 1;
  int columns_ = 0, rows_ = 0;
};

}  // namespace tessera

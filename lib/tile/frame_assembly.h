// SPDX-License-Identifier: Apache-2.0
// A frame put together from its tiles: the colour, and optionally the per-pixel variance and
// sample counts, with which of the grid's tiles are in. The one place tile pixels are copied into a
// frame: the in-process render, the client writing farm frames and the coordinator's monitor all
// use it, so a frame is laid out the same way wherever it is assembled.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "image/image.h"
#include "tile/tile_grid.h"
#include "tile/tile_result.h"

namespace tessera {

class FrameAssembly {
 public:
  // kColour keeps the RGB only (a preview); kEstimates also the variance and spp layers.
  enum class Layers { kColour, kEstimates };

  FrameAssembly() = default;
  explicit FrameAssembly(const TileGrid& grid, Layers layers = Layers::kEstimates);

  // Places `tile` as tile `index` of the grid. Returns "" or why it does not fit: an index
  // outside the grid, a rectangle that is not that tile's, or pixel arrays of the wrong sizes.
  // A tile already in is left as it is (the first copy wins): "" with *placed false.
  std::string place(int index, const TileResult& tile, bool* placed = nullptr);

  bool has(int index) const { return grid_.contains(index) && in_[size_t(index)]; }
  int tiles_done() const { return tiles_done_; }
  bool complete() const { return tiles_done_ == grid_.count(); }
  const TileGrid& grid() const { return grid_; }

  const ImageRGB& image() const { return image_; }
  const std::vector<float>& variance() const { return variance_; }  // empty with kColour
  const std::vector<uint32_t>& spp() const { return spp_; }         // empty with kColour
  // The layers, moved out (the assembly is empty afterwards).
  ImageRGB take_image() { return std::move(image_); }
  std::vector<float> take_variance() { return std::move(variance_); }
  std::vector<uint32_t> take_spp() { return std::move(spp_); }

 private:
  TileGrid grid_;
  ImageRGB image_;
  std::vector<float> variance_;
  std::vector<uint32_t> spp_;
  std::vector<bool> in_;
  int tiles_done_ = 0;
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// A finished tile: a rectangle of one frame rendered to float HDR RGB with the per-pixel
// estimated variance, the samples each pixel took, and the counts of rays traced. What a worker
// sends, the coordinator stores and forwards, and a client (or an in-process render) assembles.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "tile/block_stat.h"
#include "tile/tile_rect.h"

namespace tessera {

struct RayCounts {
  uint64_t camera = 0;      // primary rays
  uint64_t shadow = 0;      // shadow rays (point, directional and area lights)
  uint64_t secondary = 0;   // reflection and refraction rays
  uint64_t nonfinite_samples = 0;  // samples whose radiance was NaN/Inf and were replaced by 0
  uint64_t total() const { return camera + shadow + secondary; }
  RayCounts& operator+=(const RayCounts& o) {
    camera += o.camera;
    shadow += o.shadow;
    secondary += o.secondary;
    nonfinite_samples += o.nonfinite_samples;
    return *this;
  }
};

struct TileResult {
  TileRect rect;
  std::vector<float> rgb;       // 3 * width * height, row-major, the mean of the pixel's samples
  std::vector<float> variance;  // width * height: estimated variance of the pixel's value (mean
                                // over R, G, B), from its two independent sample streams
  std::vector<uint32_t> spp;    // width * height: samples the pixel took
  RayCounts rays;
  double seconds = 0;           // wall time spent rendering the tile
  // Frame-target renders only: the statistics of the blocks whose first pixel lies in the tile.
  std::vector<BlockStat> blocks;

  // A tile of `rect` with every pixel black, no variance and no samples, for a renderer to fill.
  static TileResult blank(const TileRect& rect) {
    TileResult t;
    t.rect = rect;
    const size_t pixels = size_t(rect.width) * size_t(rect.height);
    t.rgb.assign(pixels * 3, 0.0f);
    t.variance.assign(pixels, 0.0f);
    t.spp.assign(pixels, 0);
    return t;
  }
};

}  // namespace tessera

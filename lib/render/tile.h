// The unit of work of the farm: a rectangle of one frame, rendered to float HDR RGB with the
// per-pixel estimated variance, the samples each pixel took, and the counts of rays traced.
#pragma once

#include <cstdint>
#include <vector>

namespace tessera {

struct TileRect {
  int x0 = 0, y0 = 0;        // top-left pixel, image coordinates (y down)
  int width = 0, height = 0;
  bool operator==(const TileRect&) const = default;
};

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
};

// Splits a width x height frame into tiles of `tile` pixels, row-major order.
std::vector<TileRect> split_into_tiles(int width, int height, int tile);

}  // namespace tessera

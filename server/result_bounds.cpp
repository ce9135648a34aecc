// SPDX-License-Identifier: Apache-2.0
#include "result_bounds.h"

#include <fmt/format.h>

#include <cstring>

namespace tessera::server {

namespace {

// Clocks differ in resolution and a result waits in the worker's batch and the network: a
// render time within this much of the lease's age is taken as measured.
constexpr double kClockSlackSeconds = 1.0;

// The largest per-pixel count in a little-endian uint32 array (validate_tile checked its size).
uint32_t max_count(const std::string& le) {
  uint32_t most = 0;
  for (size_t i = 0; i + 4 <= le.size(); i += 4) {
    uint32_t v;
    std::memcpy(&v, le.data() + i, 4);  // x86 and ARM: little-endian, as the wire
    most = std::max(most, v);
  }
  return most;
}

}  // namespace

std::string check_result_bounds(const tessera::v1::TileData& tile, const ResultBounds& b) {
  if (tile.seconds() > b.lease_age_seconds + kClockSlackSeconds) {
    return fmt::format("render time {:g} s is longer than its lease has existed ({:.3f} s)", tile.seconds(),
                       b.lease_age_seconds);
  }
  const uint64_t spp = tile.spp().empty() ? tile.uniform_spp() : max_count(tile.spp());
  if (spp > uint64_t(b.max_spp)) {
    return fmt::format("a pixel took {} samples, more than the job's {}", spp, b.max_spp);
  }
  const uint64_t most_camera = uint64_t(b.pixels) * uint64_t(b.max_spp);
  if (tile.rays().camera() > most_camera) {
    return fmt::format("camera ray count {} is above the tile's {} pixels x {} samples", tile.rays().camera(),
                       b.pixels, b.max_spp);
  }
  return {};
}

}  // namespace tessera::server

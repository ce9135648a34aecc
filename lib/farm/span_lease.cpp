// SPDX-License-Identifier: Apache-2.0
#include "span_lease.h"

#include <cstdint>
#include <limits>
#include <string>

#include "farm/tile_codec.h"
#include "tile/tile_grid.h"

namespace tessera::farm {

namespace v1 = tessera::v1;

std::string split_span(const v1::Assignment& a, std::vector<v1::Assignment>* tiles) {
  tiles->clear();
  const int count = a.tile_count();
  if (count == 0 || count == 1) {  // a single-tile lease: as before spans, untouched
    tiles->push_back(a);
    return "";
  }
  if (count < 0 || count > kMaxSpanTiles) {
    return "span of " + std::to_string(count) + " tiles (1 to " + std::to_string(kMaxSpanTiles) + ")";
  }
  // TileGrid counts columns as (width + size - 1) / size in int: sides that would overflow that
  // are no frame anyone renders, and are refused with the rest.
  constexpr int64_t kIntMax = std::numeric_limits<int>::max();
  if (a.tile_size() <= 0 || a.frame_width() <= 0 || a.frame_height() <= 0 ||
      int64_t(a.frame_width()) + a.tile_size() - 1 > kIntMax ||
      int64_t(a.frame_height()) + a.tile_size() - 1 > kIntMax) {
    return "span with a tile grid of " + std::to_string(a.frame_width()) + "x" + std::to_string(a.frame_height()) +
           " pixels in tiles of " + std::to_string(a.tile_size());
  }
  if (!a.sample_plan().empty()) return "span with a sample plan (only single-tile leases carry one)";
  const TileGrid grid(a.frame_width(), a.frame_height(), a.tile_size());
  // In 64 bits: over a large frame in small tiles, TileGrid::count() (columns * rows) overflows.
  const int64_t tiles_in_grid = int64_t(grid.columns()) * grid.rows();
  const int64_t first = a.tile_index(), end = first + count;
  if (first < 0 || end > tiles_in_grid || end - 1 > kIntMax) {
    return "span of tiles " + std::to_string(first) + " to " + std::to_string(end - 1) + " in a grid of " +
           std::to_string(tiles_in_grid) + " tiles";
  }
  // Every index of the span is an int inside the grid: TileGrid::rect, which uses only the
  // columns, the size and the sides, cuts it without overflow.
  if (farm::from_proto(a.rect()) != grid.rect(int(first))) {
    return "span whose rect is not tile " + std::to_string(first) + "'s in its grid";
  }
  tiles->reserve(size_t(count));
  for (int i = 0; i < count; ++i) {
    v1::Assignment& t = tiles->emplace_back(a);
    t.set_tile_index(int(first) + i);
    t.clear_tile_count();
    farm::to_proto(grid.rect(int(first) + i), t.mutable_rect());
  }
  return "";
}

}  // namespace tessera::farm

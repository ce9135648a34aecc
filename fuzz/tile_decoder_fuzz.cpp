// SPDX-License-Identifier: Apache-2.0
// Fuzz target: the tile decoder, on a serialized tessera.v1.TileData as a client receives it from
// the coordinator (and the coordinator from a worker). An accepted tile is placed into a 64x48
// image the way the client does, so ASan catches a rectangle the checks let through wrongly.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <google/protobuf/stubs/logging.h>

#include "farm/overrides_codec.h"
#include "farm/tile_codec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    google::protobuf::SetLogHandler(nullptr);  // invalid UTF-8 in a string field is logged, not a bug
    return true;
  }();
  (void)quiet;
  tessera::v1::TileData tile;
  if (!tile.ParseFromArray(data, int(size))) return 0;
  constexpr int kW = 64, kH = 48;
  tessera::TileResult r;
  if (tessera::farm::decode_tile_in_image(tile, kW, kH, &r).empty()) {
    const auto& q = r.rect;
    if (r.rgb.size() != size_t(3) * size_t(q.width) * size_t(q.height)) std::abort();
    if (r.variance.size() != size_t(q.width) * size_t(q.height)) std::abort();
    std::vector<float> rgb(size_t(3) * kW * kH), variance(size_t(kW) * kH);
    for (int y = 0; y < q.height; ++y) {
      const size_t src = size_t(y) * size_t(q.width);
      std::copy_n(&r.rgb[3 * src], 3 * size_t(q.width), &rgb.at(3 * (size_t(q.y0 + y) * kW + size_t(q.x0))));
      std::copy_n(&r.variance[src], size_t(q.width), &variance.at(size_t(q.y0 + y) * kW + size_t(q.x0)));
    }
  }
  // The coordinator's check against a lease's 16x16 rectangle must never crash either.
  (void)tessera::farm::check_tile(tile, 16, 16);
  // Overrides travel in the same messages: the wire-to-struct conversion, on the same bytes.
  tessera::v1::ImageOverrides o;
  if (o.ParseFromArray(data, int(size))) {
    try {
      (void)tessera::farm::from_proto(o);
    } catch (const tessera::SceneError&) {
    }
  }
  return 0;
}

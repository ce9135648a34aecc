// SPDX-License-Identifier: Apache-2.0
// A rectangle of one frame: the unit of work of the farm. A plain value, shared by the scheduler
// (which hands tiles out), the renderer (which fills them), the wire codec and the assemblers.
#pragma once

#include <cstdint>

namespace tessera {

struct TileRect {
  int x0 = 0, y0 = 0;  // top-left pixel, image coordinates (y down)
  int width = 0, height = 0;
  int64_t pixels() const { return int64_t(width) * int64_t(height); }
  bool operator==(const TileRect&) const = default;
};

}  // namespace tessera

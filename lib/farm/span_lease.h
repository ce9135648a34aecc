// SPDX-License-Identifier: Apache-2.0
// Span leases (worker_service.proto, Assignment.tile_count): one lease covering several
// consecutive tiles of one frame. A worker (tessera-worker, and the simulated one of
// bench/farm) renders each tile as a task of its own, so it cuts the span into one single-tile
// assignment per tile, each rendered and reported exactly as a single-tile lease is.
#pragma once

#include <string>
#include <vector>

#include "tessera/v1/worker_service.pb.h"

namespace tessera::farm {

// The most tiles one span lease may cover: a bound on what one message can make this worker
// allocate, not a limit of the protocol's tile grids.
inline constexpr int kMaxSpanTiles = 4096;

// Whether the assignment is a span lease (more than one tile).
inline bool is_span(const tessera::v1::Assignment& a) { return a.tile_count() > 1; }

// Cuts `a` into its tiles, in index order, into `tiles` (replaced): a single-tile lease
// (tile_count 0 or 1) as it came; each tile of a span as a copy of the span with its own
// tile_index and rect (cut from the frame's grid) and no tile_count. Returns "" or what is wrong
// with the span (then `tiles` is empty): a tile count outside 1..kMaxSpanTiles, a grid that is not
// positive, a tile outside the grid, a first rect that is not the grid's, or a sample plan (only
// single-tile leases carry one).
std::string split_span(const tessera::v1::Assignment& a, std::vector<tessera::v1::Assignment>* tiles);

}  // namespace tessera::farm

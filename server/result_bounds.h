// SPDX-License-Identifier: Apache-2.0
// The physical bounds a tile's statistics must meet before they count: a render cannot take
// longer than its lease has existed, a pixel cannot take more samples than the job allows, and
// a tile cannot trace more camera rays than its pixels took samples. Finite but absurd figures
// (a 1e300 s render, 2^40 rays) would otherwise reach the job's sums, the reports and the
// tessera_work_seconds gauge an autoscaler reads.
#pragma once

#include <cstdint>
#include <string>

#include "tessera/v1/common.pb.h"

namespace tessera::server {

struct ResultBounds {
  double lease_age_seconds = 0;  // from the lease's issue to the result's arrival
  int64_t pixels = 0;            // the tile's
  int max_spp = 0;               // the job's most samples per pixel (JobSpec::spp)
};

// Empty when the tile's render time, sample counts and camera rays are within the bounds; else
// what is out of them, naming the figure and its bound. The tile has passed farm::validate_tile.
std::string check_result_bounds(const tessera::v1::TileData& tile, const ResultBounds& b);

}  // namespace tessera::server

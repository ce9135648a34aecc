// SPDX-License-Identifier: Apache-2.0
// Where a lattice frame's camera rays and time went (render/lattice_sampler.h): the corners every
// pixel shares, the audits of the smooth pixels, the edge pixels' samples. It is what bounds the
// sampler's speed against a peer's at equal error (bench/povray/pov_compare prints it).
#pragma once

#include <cstdint>

namespace tessera {

struct LatticeCost {
  // Camera rays of each kind (their shadow and secondary rays are in the frame's RayCounts).
  uint64_t corner_rays = 0, audit_rays = 0, edge_rays = 0;
  int64_t smooth_pixels = 0, audited_pixels = 0, edge_pixels = 0;
  // Wall seconds of each stage: tracing the lattice; classifying the pixels from it; settling the
  // smooth pixels and tracing their audits; the edge pixels' passes, planning included.
  double corner_seconds = 0, classify_seconds = 0, audit_seconds = 0, pass_seconds = 0;
  int passes = 0;
};

}  // namespace tessera

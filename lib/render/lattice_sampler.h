// SPDX-License-Identifier: Apache-2.0
// The lattice sampler (SamplerKind::kLattice): a frame target's pilot that traces one unjittered
// lattice of pixel corners for the whole frame, shared by the four pixels around each corner.
//
// Why: on smooth shading a jittered sample's error is of the order of the shading gradient, the
// mean of a pixel's four corners' of its second derivative (for L quadratic across the pixel,
// exactly -(Lxx + Lyy) / 12): far smaller on most of a Whitted image, for one ray a pixel.
//
//  - Smooth pixels: where the lattice's second differences along the pixel's sides are small
//    (corner_curvature), a pixel's value is the mean of its corners: the integral of their
//    bilinear interpolant P over the pixel.
//  - Its error estimate: an audit. Each smooth pixel draws, with a known probability q (larger
//    where its second differences come near the threshold or its neighbours are edges), two
//    hold-out samples x1, x2 uniform in the pixel, independent of the lattice and of each other.
//    With e the pixel's error (the integral of L - P over it), (L(x1) - P(x1)) (L(x2) - P(x2)) / q
//    is an unbiased estimate of e^2, and 0 where there is no audit; their mean over the frame (a
//    Horvitz-Thompson sum) estimates the smooth pixels' share of the frame's MSE, sub-pixel
//    features the lattice missed included, in proportion to their area. (One sample's
//    (L(x) - P(x))^2 would bound e^2 instead, by Jensen, but 1/p times over for a feature
//    covering a fraction p of the pixel.) A negative product is stored as 0.
//    An audit never changes its pixel nor decides where to refine: a pixel whose audit is large
//    stays as it is, and the audit measures exactly the error left there.
//  - Every other pixel is an edge pixel: it is rendered with the default sampler's two stratified
//    streams from sample 0 (bit for bit a sobol render of it), its samples allocated per allocation
//    block by the frame target's passes with the smooth pixels frozen (render/lattice_frame.h).
//
// Every corner, classification and audit is a pure function of (scene, frame, settings, global
// lattice coordinates), never of a tile or thread: the frame is the same bits for any thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "render/huge_page_allocator.h"
#include "render/lattice_cost.h"
#include "render/render_scene.h"
#include "render/sampler.h"
#include "sampling/pass_plan.h"
#include "tile/block_stat.h"
#include "tile/tile_result.h"

namespace tessera {

// The lattice of pixel corners: (width + 1) x (height + 1) radiances, row-major; on huge pages
// (render/huge_page_allocator.h), for it is written once a corner and 25 MB at 1920x1080.
using CornerLattice = std::vector<Rgb, HugePageAllocator<Rgb>>;

// Radiance at n film positions (x[i], y[i]) in pixel units (the image's top-left corner at 0, 0;
// pixel (px, py) covers [px, px + 1) x [py, py + 1)), lane i traced with samplers[i]; a non-finite
// result is counted in rays->nonfinite_samples and replaced by 0, as pixel samples are.
void trace_film_points(const RenderScene& scene, const float* x, const float* y, const PixelSampler* samplers, int n,
                       Rgb* out, RayCounts* rays);

// The pilot of a lattice frame target.
struct LatticePilot {
  // Per pixel (row-major over the frame): 1 where it is smooth; its value is then final.
  std::vector<uint8_t> smooth;
  // The smooth pixels' blocks and error as the passes take them (sampling/pass_plan.h).
  FrozenPixels frozen;
  // Per allocation block: for blocks all of whose pixels are smooth their statistics (spp 1, the
  // audited mean error; the planner never gives them more), default for the others.
  std::vector<BlockStat> stats;
  // Per pixel, set for smooth pixels: the corners' mean, the audit's estimate of its squared error
  // (bfloat16, as tiles carry it; 0 when not audited) and the samples it took (1: its share of
  // the lattice, plus the audit's two).
  std::vector<float> rgb, variance;
  std::vector<uint32_t> spp;
  RayCounts rays;
  LatticeCost cost;  // its corners', classification's and audits' part
};

// Traces the lattice and the audits (tbb::parallel_for: run it inside the caller's arena).
LatticePilot render_lattice_pilot(const RenderScene& scene);

// What the pilot decides from, exposed for tests: the curvature of the lattice at pixel (px, py),
// given the corners' radiance row-major over (width + 1) x (height + 1) corners. Along each of the
// pixel's four sides, the smaller of the two second differences (along that side, largest over
// R, G, B) centred on its ends; the largest over the sides. Why the smaller: a step between two
// corners shows in the second differences of both, so a pixel next to an edge would see it in the
// difference centred on its shared corner, but not in the other; an edge through the pixel shows
// in both, and so does curvature.
float corner_curvature(const CornerLattice& corners, int width, int height, int px, int py);

// corner_curvature of every pixel of rows [y0, y1), bit for bit, into out[py * width + px]: what
// the classification calls.
void corner_curvature_rows(const CornerLattice& corners, int width, int height, int y0, int y1, float* out);

}  // namespace tessera

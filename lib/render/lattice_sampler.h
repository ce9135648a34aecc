// SPDX-License-Identifier: Apache-2.0
// The lattice sampler (SamplerKind::kLattice): a frame target's pilot that traces one unjittered
// lattice of pixel corners for the whole frame, shared by the four pixels around each corner.
//
// Why: on smooth shading a jittered sample's error is of the order of the shading gradient, the
// mean of a pixel's four corners' of its second derivative (for L quadratic across the pixel,
// exactly -(Lxx + Lyy) / 12): far smaller on most of a Whitted image, for one ray a pixel.
//
//  - Smooth pixels: where every second difference of the lattice at the pixel's corners is small
//    (sampling/pass_plan.h's allocation blocks whose four pixels all are), a pixel's value is the
//    mean of its corners: the integral of their bilinear interpolant P over the pixel.
//  - Its error estimate: an audit. Each smooth pixel draws, with a known probability q (larger
//    where its second differences come near the threshold), one hold-out sample x uniform in the
//    pixel, independent of the lattice. (L(x) - P(x))^2 / q is an unbiased estimate of
//    E_x[(L - P)^2] >= (integral of (L - P))^2, the pixel's squared error (Jensen), and 0 where
//    there is no audit; their mean over the frame (a Horvitz-Thompson sum) bounds the frame's MSE
//    in expectation, sub-pixel features the lattice missed included, in proportion to their area.
//    An audit never changes its pixel nor decides where to refine: a pixel whose audit is large
//    stays as it is, and the audit measures exactly the error left there.
//  - Every other block is an edge block: it is rendered with the default sampler's two stratified
//    streams from sample 0 (bit for bit a sobol render of its pixels) and its samples allocated
//    by the frame target's passes with the smooth blocks frozen (sampling/pass_plan.h).
//
// Every corner, classification and audit is a pure function of (scene, frame, settings, global
// lattice coordinates), never of a tile or thread: the frame is the same bits for any thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "render/render_scene.h"
#include "tile/block_stat.h"
#include "tile/tile_result.h"

namespace tessera {

// Radiance at n film positions (x[i], y[i]) in pixel units (the image's top-left corner at 0, 0;
// pixel (px, py) covers [px, px + 1) x [py, py + 1)), lane i traced with samplers[i]; a non-finite
// result is counted in rays->nonfinite_samples and replaced by 0, as pixel samples are.
void trace_film_points(const RenderScene& scene, const float* x, const float* y, const PixelSampler* samplers, int n,
                       Rgb* out, RayCounts* rays);

// The pilot of a lattice frame target over the frame's grid of allocation blocks.
struct LatticePilot {
  // Per allocation block (row-major): 1 where all its pixels are smooth. Their values are final.
  std::vector<uint8_t> smooth_block;
  // Per allocation block: for smooth blocks their statistics (spp 1, the audited mean error; the
  // planner never gives them more), default for the others.
  std::vector<BlockStat> stats;
  // Per pixel (row-major over the frame), set for the pixels of smooth blocks: the corners' mean,
  // the audit's estimate of its squared error (bfloat16, as tiles carry it; 0 when not audited)
  // and the samples it took (1: its share of the lattice, plus its audit).
  std::vector<float> rgb, variance;
  std::vector<uint32_t> spp;
  RayCounts rays;
  int64_t smooth_pixels = 0, audited_pixels = 0;
};

// Traces the lattice and the audits (tbb::parallel_for: run it inside the caller's arena).
LatticePilot render_lattice_pilot(const RenderScene& scene);

// What the pilot decides from, exposed for tests: the largest absolute second difference (over
// R, G, B, along x and y) of the lattice at the four corners of pixel (px, py), given the corners'
// radiance row-major over (width + 1) x (height + 1) corners.
float corner_curvature(const std::vector<Rgb>& corners, int width, int height, int px, int py);

}  // namespace tessera

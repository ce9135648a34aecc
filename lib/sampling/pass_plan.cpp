// SPDX-License-Identifier: Apache-2.0
#include "sampling/pass_plan.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

namespace tessera {

namespace {

// How a block's MSE is assumed to fall with spp before two passes have measured it: the rate of
// an edge under the stratified samplers (N^-1.5; smooth pixels fall faster, independent samples
// as N^-1). Measured on the showcase scenes: 1.5 lands the frame's estimate at 0.93-1.0x the
// target, where 1 (independent samples) overshot it to 0.5-0.8x, paying for error nobody asked
// for (docs/performance.md, "Target-error renders against uniform spp").
constexpr double kFirstRate = 1.5;

// What the allocation shares samples by, each block's own shape (its error, or its stratified
// floor if larger) raised to
//  - its own error averaged half and half with the mean over its 3x3 neighbourhood (its own
//    error and its eight neighbours' shapes). A block's estimate after the pilot has few degrees
//    of freedom; a block that reads low by chance would be left at the pilot's count with an
//    estimate that stays low, and the frame's estimate with it (measured with 4x4 blocks:
//    0.69-0.73x the measured error at the tightest targets without this, 0.89-1.02x with it).
//    Edges and glass continue across blocks, so the neighbours say what a block's own few
//    samples may have missed;
//  - the contrast floor, kContrastWeight d / n^1.5, d the largest mean squared difference between
//    its mean value and that of a neighbour across an edge (left, right, above, below), n its
//    samples. Where every sample of a pixel fell on one side of an edge, its two streams agree and
//    its estimate reads 0 however wrong the pixel is: with a pilot of 2 samples, the pixels of the
//    Whitted showcase's horizon (2.5% sky) and of checker edges whose samples missed the smaller
//    side held half the frame's error and 5% of its estimate, and on 2x2 blocks such an edge often
//    lies between two blocks that each look flat inside. The neighbour across the edge shows what
//    the block's own samples could not; the floor falls as an edge's error does under the
//    stratified samplers (spp^-1.5). Measured (bench/speed_error, 3 seeds a target): without
//    it, the frame's estimate fell to 0.63-0.77x its measured error at the tightest targets on
//    Whitted. Weights from 0.1 to 1 spend about the same samples for the same measured error
//    (within 5-7%); larger ones make the estimate more honest and the frame overshoot its target
//    more. At 0.25 the Cornell box's estimate was 0.79x at one target of five, at 0.35 0.84x, at
//    0.5 0.87-1.11x everywhere, for 5-7% more samples on Whitted and the bunny.
// Only the shares move: the frame's level (the target) stays each block's own error.
constexpr double kContrastWeight = 0.5;

double contrast_floor(const std::vector<BlockStat>& stats, const BlockGrid& grid, int b) {
  const int cx = b % grid.cols, cy = b / grid.cols;
  const BlockStat& me = stats[size_t(b)];
  double d = 0;
  for (const auto [dx, dy] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
    const int x = cx + dx, y = cy + dy;
    if (x < 0 || y < 0 || x >= grid.cols || y >= grid.rows) continue;
    const BlockStat& q = stats[size_t(y * grid.cols + x)];
    double e = 0;
    for (size_t c = 0; c < 3; ++c) {
      const double t = double(me.mean[c]) - double(q.mean[c]);
      e += t * t;
    }
    d = std::max(d, e / 3);
  }
  const double n = double(std::max(me.spp, 1u));
  return kContrastWeight * d / (n * std::sqrt(n));
}

// Block b's statistics with its shape as the allocation shares samples by.
BlockStat shaped_stat(const std::vector<BlockStat>& stats, const BlockGrid& grid, int b) {
  const int cx = b % grid.cols, cy = b / grid.cols;
  const BlockStat& me = stats[size_t(b)];
  double sum = me.mse;
  int n = 1;
  for (int y = std::max(0, cy - 1); y <= std::min(grid.rows - 1, cy + 1); ++y) {
    for (int x = std::max(0, cx - 1); x <= std::min(grid.cols - 1, cx + 1); ++x) {
      if (x == cx && y == cy) continue;
      sum += stats[size_t(y * grid.cols + x)].shape_mse;
      ++n;
    }
  }
  const double pooled = 0.5 * me.mse + 0.5 * sum / double(n);
  BlockStat out = me;
  out.shape_mse = std::max({me.shape_mse, pooled, contrast_floor(stats, grid, b)});
  return out;
}

std::vector<BlockStat> shaped(const std::vector<BlockStat>& stats, const BlockGrid& grid) {
  std::vector<BlockStat> out(stats.size());
  for (int b = 0; b < grid.count(); ++b) out[size_t(b)] = shaped_stat(stats, grid, b);
  return out;
}

}  // namespace

double first_rate(SamplerKind sampler) { return sampler == SamplerKind::kIndependent ? 1.0 : kFirstRate; }

BlockGrid::Range BlockGrid::meeting(const TileRect& rect) const {
  constexpr int B = kAllocationBlock;
  return {rect.x0 / B, rect.y0 / B, (rect.x0 + rect.width + B - 1) / B, (rect.y0 + rect.height + B - 1) / B};
}

int BlockGrid::origins_in(const TileRect& rect) const {
  constexpr int B = kAllocationBlock;
  const int cols_in = (rect.x0 + rect.width + B - 1) / B - (rect.x0 + B - 1) / B;
  const int rows_in = (rect.y0 + rect.height + B - 1) / B - (rect.y0 + B - 1) / B;
  return std::max(0, cols_in) * std::max(0, rows_in);
}

BlockStat updated_stat(const BlockStat& before, const BlockStat& now) {
  if (now.spp == before.spp) return before;
  BlockStat s = now;
  if (before.spp > 0 && before.spp < now.spp && before.shape_mse > 0 && now.shape_mse > 0) {
    s.rate = std::clamp(std::log(before.shape_mse / now.shape_mse) / std::log(double(now.spp) / double(before.spp)),
                        1.0, 2.5);
  }
  return s;
}

std::optional<std::vector<uint32_t>> next_pass_counts(const std::vector<BlockStat>& stats, const BlockGrid& grid,
                                                      const ImageSettings& img, int passes_done) {
  if (passes_done >= kMaxTargetPasses) return std::nullopt;
  std::vector<uint32_t> have(stats.size());
  for (size_t b = 0; b < stats.size(); ++b) have[b] = stats[b].spp;
  const AllocationBounds bounds{img.target_rmse * img.target_rmse, uint32_t(img.first_spp()), uint32_t(img.max_spp)};
  if (predicted_frame_mse(stats, have) <= bounds.frame_mse) return std::nullopt;
  std::vector<uint32_t> want = allocate_samples(shaped(stats, grid), bounds);
  if (want == have) return std::nullopt;
  return want;
}

std::optional<std::vector<uint32_t>> next_pass_counts(const std::vector<BlockStat>& stats, const BlockGrid& grid,
                                                      const ImageSettings& img, int passes_done,
                                                      const FrozenPixels& frozen) {
  if (passes_done >= kMaxTargetPasses) return std::nullopt;
  // The open blocks alone, shaped among all their neighbours, and the target left to them.
  std::vector<BlockStat> open, open_now;
  std::vector<uint32_t> have;
  std::vector<size_t> index;
  double open_pixels = 0;
  for (size_t b = 0; b < stats.size(); ++b) {
    if (frozen.blocks[b] || stats[b].pixels == 0) continue;
    open.push_back(shaped_stat(stats, grid, int(b)));
    open_now.push_back(stats[b]);
    have.push_back(stats[b].spp);
    index.push_back(b);
    open_pixels += double(stats[b].pixels);
  }
  if (open.empty()) return std::nullopt;
  const double target = img.target_rmse * img.target_rmse, pixels = double(frozen.frame_pixels);
  if ((frozen.error + predicted_frame_mse(open_now, have) * open_pixels) / pixels <= target) return std::nullopt;
  const double left = std::max((target * pixels - frozen.error) / open_pixels, 0.5 * target);
  const std::vector<uint32_t> counts =
      allocate_samples(open, {left, uint32_t(img.first_spp()), uint32_t(img.max_spp)});
  if (counts == have) return std::nullopt;
  std::vector<uint32_t> want(stats.size());
  for (size_t b = 0; b < stats.size(); ++b) want[b] = stats[b].spp;
  for (size_t i = 0; i < index.size(); ++i) want[index[i]] = counts[i];
  return want;
}

SamplePlan tile_plan(const BlockGrid& grid, const TileRect& rect, const std::vector<uint32_t>& counts) {
  const BlockGrid::Range r = grid.meeting(rect);
  SamplePlan plan;
  plan.reserve(size_t(r.count()));
  for (int row = r.row0; row < r.row1; ++row) {
    for (int col = r.col0; col < r.col1; ++col) plan.push_back(counts[size_t(row * grid.cols + col)]);
  }
  return plan;
}

std::string encode_plan(const SamplePlan& plan) {
  std::string out(plan.size() * 4, '\0');
  for (size_t i = 0; i < plan.size(); ++i) {
    for (int k = 0; k < 4; ++k) out[4 * i + size_t(k)] = char((plan[i] >> (8 * k)) & 0xff);
  }
  return out;
}

std::string decode_plan(const std::string& bytes, SamplePlan* plan) {
  if (bytes.size() % 4 != 0) {
    return "sample plan of " + std::to_string(bytes.size()) + " bytes is not a whole number of 4-byte counts";
  }
  plan->assign(bytes.size() / 4, 0);
  for (size_t i = 0; i < plan->size(); ++i) {
    uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v |= uint32_t(uint8_t(bytes[4 * i + size_t(k)])) << (8 * k);
    (*plan)[i] = v;
  }
  return "";
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "render/frame_target.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "render/huge_page_allocator.h"
#include "render/lattice_frame.h"
#include "render/pixel_samples.h"
#include "tile/bfloat16.h"

namespace tessera {

BlockStat block_stat(int64_t block, const PixelEstimate* pixels, int w, int h, uint32_t spp, uint64_t rays,
                     SamplerKind sampler) {
  BlockStat s;
  s.block = block;
  s.spp = spp;
  s.pixels = uint32_t(w * h);
  // The estimate as tiles store it (bfloat16) and, for the shape, for stratified samplers the
  // floor below which an edge pixel's estimate is not trusted (PixelEstimate::stratified_floor),
  // whichever is larger; summed in row order.
  // Its mean value, for the planner's contrast floor (sampling/pass_plan.cpp).
  double sum = 0, shape = 0, mean[3] = {0, 0, 0};
  for (int i = 0; i < w * h; ++i) {
    const double v = double(round_to_bfloat16(float(pixels[i].variance(sampler))));
    sum += v;
    shape += sampler == SamplerKind::kSobol ? std::max(v, pixels[i].stratified_floor()) : v;
    for (int c = 0; c < 3; ++c) mean[c] += double(pixels[i].mean(c));
  }
  for (int c = 0; c < 3; ++c) s.mean[size_t(c)] = float(mean[c] / double(w * h));
  s.mse = sum / double(s.pixels);
  s.shape_mse = shape / double(s.pixels);
  s.cost = spp > 0 ? double(rays) / (double(spp) * double(s.pixels)) : 1.0;
  s.rate = first_rate(sampler);
  return s;
}

TileResult render_tile_planned(const RenderScene& scene, const TileRect& rect, const SamplePlan& plan) {
  const auto start = std::chrono::steady_clock::now();
  const ImageSettings& img = scene.image();
  if (img.sampler == SamplerKind::kLattice) {
    // Its pilot classifies pixels from a lattice that crosses tiles, and the coordinator's planner
    // does not keep its smooth pixels frozen: in-process renders only.
    throw std::invalid_argument("render_tile_planned: the lattice sampler renders a frame target in-process only "
                                "(tessera render), not on a farm");
  }
  constexpr int B = kAllocationBlock;
  const BlockGrid grid(img.width, img.height);
  const BlockGrid::Range r = grid.meeting(rect);
  if (!plan.empty() && plan.size() != size_t(r.count())) {
    throw std::invalid_argument("sample plan has " + std::to_string(plan.size()) + " counts, the tile meets " +
                                std::to_string(r.count()) + " blocks");
  }
  TileResult out = TileResult::blank(rect);
  PixelEstimate block[B * B];
  size_t i = 0;
  for (int row = r.row0; row < r.row1; ++row) {
    for (int col = r.col0; col < r.col1; ++col, ++i) {
      const uint32_t n = plan.empty() ? uint32_t(img.first_spp()) : plan[i];
      if (n < uint32_t(img.first_spp()) || n > uint32_t(std::max(img.max_spp, img.first_spp()))) {
        throw std::invalid_argument("sample plan asks " + std::to_string(n) + " samples of block (" +
                                    std::to_string(col) + ", " + std::to_string(row) + "), outside [" +
                                    std::to_string(img.first_spp()) + ", " + std::to_string(img.max_spp) + "]");
      }
      const int bx = col * B, by = row * B;
      const int w = std::min(B, img.width - bx), h = std::min(B, img.height - by);
      std::fill(block, block + B * B, PixelEstimate{});
      RayCounts rays;
      render_samples(scene, {bx, by, w, h}, 0, n, block, &rays);
      out.rays += rays;
      for (int y = std::max(by, rect.y0); y < std::min(by + h, rect.y0 + rect.height); ++y) {
        for (int x = std::max(bx, rect.x0); x < std::min(bx + w, rect.x0 + rect.width); ++x) {
          store_pixel(block[(y - by) * w + (x - bx)], img.sampler,
                      size_t(y - rect.y0) * size_t(rect.width) + size_t(x - rect.x0), &out);
        }
      }
      if (bx >= rect.x0 && by >= rect.y0) {  // its first pixel is this tile's: report it
        out.blocks.push_back(block_stat(int64_t(row) * grid.cols + col, block, w, h, n, rays.total(), img.sampler));
      }
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

FrameResult render_frame_to_target(const RenderScene& scene, int threads,
                                   const std::function<void(int64_t, int64_t)>& progress) {
  if (scene.image().sampler == SamplerKind::kLattice) return render_frame_lattice(scene, threads, progress);
  const auto start = std::chrono::steady_clock::now();
  const ImageSettings& img = scene.image();
  const BlockGrid grid(img.width, img.height);
  constexpr int B = kAllocationBlock;
  const size_t pixels = size_t(img.width) * size_t(img.height);
  // Every pixel's running estimate, block by block (block b's pixels at b * B * B, row-major):
  // 80 bytes a pixel, on huge pages (render/huge_page_allocator.h).
  std::vector<PixelEstimate, HugePageAllocator<PixelEstimate>> est(size_t(grid.count()) * B * B);
  std::vector<BlockStat> stats(size_t(grid.count()));
  std::vector<RayCounts, HugePageAllocator<RayCounts>> rays_per_block(size_t(grid.count()));
  std::vector<uint32_t> want(size_t(grid.count()), uint32_t(img.first_spp()));
  std::atomic<int64_t> samples_done{0};
  int64_t samples_planned = 0;
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  for (int passes = 0;;) {
    for (int b = 0; b < grid.count(); ++b) samples_planned += int64_t(want[size_t(b)] - stats[size_t(b)].spp) * B * B;
    arena.execute([&] {
      tbb::parallel_for(0, grid.count(), [&](int b) {
        BlockStat& s = stats[size_t(b)];
        const uint32_t from = s.spp, to = want[size_t(b)];
        if (to <= from) return;
        const int bx = (b % grid.cols) * B, by = (b / grid.cols) * B;
        const int w = std::min(B, img.width - bx), h = std::min(B, img.height - by);
        PixelEstimate* block = &est[size_t(b) * B * B];
        RayCounts& rays = rays_per_block[size_t(b)];
        render_samples(scene, {bx, by, w, h}, from, to, block, &rays);
        s = updated_stat(s, block_stat(b, block, w, h, to, rays.total(), img.sampler));
        if (progress) progress(samples_done += int64_t(to - from) * w * h, samples_planned);
      });
    });
    auto next = next_pass_counts(stats, grid, img, ++passes);
    if (!next) break;
    want = std::move(*next);
  }

  FrameResult out;
  out.image = ImageRGB(img.width, img.height);
  out.variance.assign(pixels, 0.0f);
  out.spp.assign(pixels, 0);
  for (int b = 0; b < grid.count(); ++b) {
    const int bx = (b % grid.cols) * B, by = (b / grid.cols) * B;
    const int w = std::min(B, img.width - bx), h = std::min(B, img.height - by);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const PixelEstimate& e = est[size_t(b) * B * B + size_t(y * w + x)];
        const size_t i = size_t(by + y) * size_t(img.width) + size_t(bx + x);
        float* rgb = out.image.at(bx + x, by + y);
        for (int c = 0; c < 3; ++c) rgb[c] = e.mean(c);
        out.variance[i] = round_to_bfloat16(float(e.variance(img.sampler)));
        out.spp[i] = e.samples();
      }
    }
    out.rays += rays_per_block[size_t(b)];
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.settings = img;
  return out;
}

}  // namespace tessera

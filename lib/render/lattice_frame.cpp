// SPDX-License-Identifier: Apache-2.0
#include "render/lattice_frame.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <vector>

#include "render/frame_target.h"
#include "render/huge_page_allocator.h"
#include "render/lattice_sampler.h"
#include "render/pixel_samples.h"
#include "tile/bfloat16.h"

namespace tessera {

namespace {

constexpr int B = kAllocationBlock;

// The edge pixels of a frame, block by block: block b's are edge[first[b]] .. edge[first[b + 1]).
// Only they keep a running estimate (a tenth of a Whitted frame's pixels, where an estimate
// for every pixel was a sixth of the frame's time in zeroing and page faults).
struct EdgePixels {
  struct Pixel {
    int x = 0, y = 0;
    PixelEstimate est;
  };
  std::vector<Pixel, HugePageAllocator<Pixel>> edge;  // render/huge_page_allocator.h
  std::vector<size_t> first;

  EdgePixels(const LatticePilot& pilot, const BlockGrid& grid) : first(size_t(grid.count()) + 1, 0) {
    edge.reserve(size_t(pilot.cost.edge_pixels));
    for (int b = 0; b < grid.count(); ++b) {
      first[size_t(b)] = edge.size();
      const int bx = (b % grid.cols) * B, by = (b / grid.cols) * B;
      for (int y = by; y < std::min(by + B, grid.height); ++y) {
        for (int x = bx; x < std::min(bx + B, grid.width); ++x) {
          if (!pilot.smooth[size_t(y) * size_t(grid.width) + size_t(x)]) edge.push_back({x, y, {}});
        }
      }
    }
    first[size_t(grid.count())] = edge.size();
  }

  // Block b's statistics after `spp` samples of each of its edge pixels and `rays` rays.
  BlockStat stat(int b, uint32_t spp, uint64_t rays) const {
    PixelEstimate est[B * B];
    int n = 0;
    for (size_t i = first[size_t(b)]; i < first[size_t(b) + 1]; ++i) est[n++] = edge[i].est;
    return block_stat(b, est, n, 1, spp, rays, SamplerKind::kSobol);
  }
};

}  // namespace

FrameResult render_frame_lattice(const RenderScene& scene, int threads,
                                 const std::function<void(int64_t, int64_t)>& progress) {
  const auto start = std::chrono::steady_clock::now();
  const ImageSettings& img = scene.image();
  const BlockGrid grid(img.width, img.height);
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  LatticePilot pilot;
  arena.execute([&] { pilot = render_lattice_pilot(scene); });
  const auto passes_start = std::chrono::steady_clock::now();
  EdgePixels edges(pilot, grid);
  std::vector<BlockStat> stats = std::move(pilot.stats);
  std::vector<uint32_t> want(size_t(grid.count()), uint32_t(img.first_spp()));
  for (int b = 0; b < grid.count(); ++b) {
    if (pilot.frozen.blocks[size_t(b)]) want[size_t(b)] = stats[size_t(b)].spp;
  }
  std::vector<double> block_rays(size_t(grid.count()), 0.0);  // each block's share of its rows' rays
  std::vector<RayCounts> row_rays(size_t(grid.rows));
  std::atomic<int64_t> samples_done{0};
  int64_t samples_planned = 0;
  int passes = 0;
  for (;;) {
    for (int b = 0; b < grid.count(); ++b) {
      const int64_t n = int64_t(edges.first[size_t(b) + 1] - edges.first[size_t(b)]);
      samples_planned += int64_t(want[size_t(b)] - std::min(want[size_t(b)], stats[size_t(b)].spp)) * n;
    }
    arena.execute([&] {
      tbb::parallel_for(0, grid.rows, [&](int row) {
        std::vector<PixelRun> runs;
        std::vector<int64_t> block_samples(size_t(grid.cols), 0);
        for (int col = 0; col < grid.cols; ++col) {
          const int b = row * grid.cols + col;
          const uint32_t from = stats[size_t(b)].spp, to = want[size_t(b)];
          if (to <= from) continue;
          for (size_t i = edges.first[size_t(b)]; i < edges.first[size_t(b) + 1]; ++i) {
            runs.push_back({edges.edge[i].x, edges.edge[i].y, from, to, &edges.edge[i].est});
            block_samples[size_t(col)] += int64_t(to - from);
          }
        }
        if (runs.empty()) return;
        RayCounts rays;
        render_pixel_runs(scene, runs.data(), runs.size(), &rays);
        row_rays[size_t(row)] += rays;
        int64_t total = 0;
        for (int64_t n : block_samples) total += n;
        for (int col = 0; col < grid.cols; ++col) {
          if (block_samples[size_t(col)] == 0) continue;
          const int b = row * grid.cols + col;
          block_rays[size_t(b)] += double(rays.total()) * double(block_samples[size_t(col)]) / double(total);
          stats[size_t(b)] = updated_stat(stats[size_t(b)], edges.stat(b, want[size_t(b)],
                                                                       uint64_t(std::llround(block_rays[size_t(b)]))));
        }
        if (progress) progress(samples_done += total, samples_planned);
      });
    });
    auto next = next_pass_counts(stats, grid, img, ++passes, pilot.frozen);
    if (!next) break;
    want = std::move(*next);
  }

  // The smooth pixels as the pilot left them, the edge pixels from their estimates.
  FrameResult out;
  out.image.width = img.width;
  out.image.height = img.height;
  out.image.rgb = std::move(pilot.rgb);
  out.variance = std::move(pilot.variance);
  out.spp = std::move(pilot.spp);
  for (const EdgePixels::Pixel& e : edges.edge) {
    const size_t p = size_t(e.y) * size_t(img.width) + size_t(e.x);
    for (int c = 0; c < 3; ++c) out.image.rgb[3 * p + size_t(c)] = e.est.mean(c);
    out.variance[p] = round_to_bfloat16(float(e.est.variance(SamplerKind::kSobol)));
    out.spp[p] = e.est.samples();
  }
  out.rays = pilot.rays;
  out.lattice = pilot.cost;
  for (const RayCounts& r : row_rays) {
    out.rays += r;
    out.lattice.edge_rays += r.camera;
  }
  out.lattice.passes = passes;
  out.lattice.pass_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - passes_start).count();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.settings = img;
  return out;
}

}  // namespace tessera

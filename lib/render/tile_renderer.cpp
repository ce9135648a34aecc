// SPDX-License-Identifier: Apache-2.0
#include "render/tile_renderer.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>

#include "render/frame_target.h"
#include "render/integrator.h"
#include "render/pixel_estimate.h"
#include "render/pixel_samples.h"
#include "tile/bfloat16.h"
#include "tile/frame_assembly.h"
#include "tile/tile_grid.h"

namespace tessera {

namespace {

// A render to a bound on every block's error (ImageSettings::block_rmse): every block of kAdaptiveBlock^2 pixels (aligned to the image) that
// meets the tile is rendered whole, its pixels checked together (adaptive.h); the pixels inside
// the tile are kept. Tiles whose edges are multiples of the block size render nothing twice.
void render_tile_adaptive(const RenderScene& scene, const TileRect& rect, TileResult* out) {
  const ImageSettings& img = scene.image();
  const double target_mse = img.block_rmse * img.block_rmse;
  const uint32_t min_spp = uint32_t(img.first_spp()), max_spp = uint32_t(img.max_spp);
  constexpr int B = kAdaptiveBlock;
  std::vector<PixelEstimate> block(size_t(B) * size_t(B));
  for (int by = rect.y0 / B * B; by < rect.y0 + rect.height; by += B) {
    for (int bx = rect.x0 / B * B; bx < rect.x0 + rect.width; bx += B) {
      const int w = std::min(B, img.width - bx), h = std::min(B, img.height - by);
      std::fill(block.begin(), block.end(), PixelEstimate{});
      uint32_t done = 0, n = min_spp, prev_n = 0;
      double prev_mse = 0;
      while (true) {
        render_samples(scene, {bx, by, w, h}, done, n, block.data(), &out->rays);
        done = n;
        if (n >= max_spp) break;
        // The block's estimated variance: per pixel the estimate as stored (tile/bfloat16.h), or for
        // stratified samplers the floor below which an edge pixel's estimate is not trusted
        // (PixelEstimate::stratified_floor), whichever is larger; summed in row order.
        double sum = 0;
        for (int y = 0; y < h; ++y) {
          for (int x = 0; x < w; ++x) {
            const PixelEstimate& e = block[size_t(y * w + x)];
            const double v = double(round_to_bfloat16(float(e.variance(img.sampler))));
            sum += img.sampler == SamplerKind::kSobol ? std::max(v, e.stratified_floor()) : v;
          }
        }
        const double mse = sum / double(w * h);
        if (!(mse > target_mse)) break;
        const uint32_t next = next_sample_count(n, mse, target_mse, max_spp, prev_n, prev_mse);
        prev_n = n;
        prev_mse = mse;
        n = next;
      }
      for (int y = std::max(by, rect.y0); y < std::min(by + h, rect.y0 + rect.height); ++y) {
        for (int x = std::max(bx, rect.x0); x < std::min(bx + w, rect.x0 + rect.width); ++x) {
          store_pixel(block[size_t((y - by) * w + (x - bx))], img.sampler,
                      size_t(y - rect.y0) * size_t(rect.width) + size_t(x - rect.x0), out);
        }
      }
    }
  }
}

}  // namespace

TileResult render_tile(const RenderScene& scene, const TileRect& rect) {
  const ImageSettings& img = scene.image();
  if (img.frame_target()) {
    // Its samples depend on the whole frame's statistics (render/frame_target.h): not a tile's work.
    throw std::invalid_argument("render_tile: a frame target (target_rmse) is rendered in passes by "
                                "render_frame, not tile by tile");
  }
  const auto start = std::chrono::steady_clock::now();
  TileResult out = TileResult::blank(rect);
  if (img.adaptive()) {
    render_tile_adaptive(scene, rect, &out);
  } else {
    // A row at a time: packets fill across its pixels at low sample counts.
    std::vector<PixelEstimate> row(size_t(rect.width));
    for (int y = rect.y0; y < rect.y0 + rect.height; ++y) {
      std::fill(row.begin(), row.end(), PixelEstimate{});
      render_samples(scene, {rect.x0, y, rect.width, 1}, 0, uint32_t(img.spp), row.data(), &out.rays);
      for (int x = 0; x < rect.width; ++x) {
        store_pixel(row[size_t(x)], img.sampler, size_t(y - rect.y0) * size_t(rect.width) + size_t(x), &out);
      }
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

double FrameResult::estimated_rmse() const {
  if (variance.empty()) return 0.0;
  double sum = 0;
  for (float v : variance) sum += double(v);
  return std::sqrt(sum / double(variance.size()));
}

FrameResult render_frame(const RenderScene& scene, int tile_size, int threads,
                         const std::function<void(int, int)>& progress) {
  if (scene.image().frame_target()) {
    return render_frame_to_target(scene, threads, [&](int64_t done, int64_t planned) {
      // Passes plan more samples as they go: progress in thousandths of the samples planned so far.
      if (progress) progress(int(done * 1000 / std::max<int64_t>(planned, 1)), 1000);
    });
  }
  const auto start = std::chrono::steady_clock::now();
  const ImageSettings& img = scene.image();
  FrameResult out;
  const TileGrid grid(img.width, img.height, tile_size);
  FrameAssembly frame(grid);
  std::mutex mutex;
  std::atomic<int> done{0};
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(0, grid.count(), [&](int i) {
      const TileResult t = render_tile(scene, grid.rect(i));
      std::lock_guard lock(mutex);
      // Cannot fail (the tile is the grid's own); if it ever did, no frame is better than a wrong one.
      if (std::string why = frame.place(i, t); !why.empty()) throw std::logic_error("render_frame: " + why);
      out.rays += t.rays;
      if (progress) progress(++done, grid.count());
    });
  });
  out.image = frame.take_image();
  out.variance = frame.take_variance();
  out.spp = frame.take_spp();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.settings = img;
  return out;
}

SampleSummary FrameResult::summary() const {
  return summarize_samples(variance, spp, image.width, image.height, settings);
}

}  // namespace tessera

#include "render/tile_renderer.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>

#include "render/integrator.h"

namespace tessera {

std::vector<TileRect> split_into_tiles(int width, int height, int tile) {
  std::vector<TileRect> tiles;
  for (int y = 0; y < height; y += tile) {
    for (int x = 0; x < width; x += tile) {
      tiles.push_back({x, y, std::min(tile, width - x), std::min(tile, height - y)});
    }
  }
  return tiles;
}

TileResult render_tile(const RenderScene& scene, const TileRect& rect) {
  const auto start = std::chrono::steady_clock::now();
  TileResult out;
  out.rect = rect;
  out.rgb.assign(size_t(rect.width) * size_t(rect.height) * 3, 0.0f);
  out.variance.assign(size_t(rect.width) * size_t(rect.height), 0.0f);
  const ImageSettings& img = scene.image();
  const auto& cam = scene.camera();
  const uint32_t spp = uint32_t(img.spp);
  std::vector<PixelSampler> samplers;
  samplers.reserve(RenderScene::kPacket);
  for (int y = rect.y0; y < rect.y0 + rect.height; ++y) {
    for (int x = rect.x0; x < rect.x0 + rect.width; ++x) {
      // Welford's running mean and variance, in double, in sample order: exact same sequence of
      // operations for this pixel wherever and however often it is rendered.
      double mean[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
      // Samples s0 .. s0+7 of this pixel form one packet: which rays share a packet depends on
      // the pixel and spp only, never on the tile or thread (see RenderScene::intersect_packet).
      for (uint32_t s0 = 0; s0 < spp; s0 += RenderScene::kPacket) {
        const int n = int(std::min<uint32_t>(RenderScene::kPacket, spp - s0));
        samplers.clear();
        Ray rays[RenderScene::kPacket];
        Rgb Ls[RenderScene::kPacket];
        for (int i = 0; i < n; ++i) {
          const PixelSampler& sampler =
              samplers.emplace_back(img.sampler, img.seed, scene.frame(), x, y, s0 + uint32_t(i), spp);
          float su, sv;
          sampler.pixel_offset(&su, &sv);
          const float u = (float(x) + su) / float(img.width);
          const float v = (float(y) + sv) / float(img.height);
          rays[i] = {Vec3f(0.0f), normalize(cam.p0 + cam.du * u + cam.dv * v)};
        }
        out.rays.camera += uint64_t(n);
        trace_radiance_packet(scene, rays, samplers.data(), n, &out.rays, Ls);
        for (int i = 0; i < n; ++i) {
          const uint32_t s = s0 + uint32_t(i);
          Rgb L = Ls[i];
          if (!is_finite(L)) {
            ++out.rays.nonfinite_samples;  // never let NaN/Inf reach a pixel; counted, not hidden
            L = Rgb(0.0f);
          }
          for (int c = 0; c < 3; ++c) {
            const double xv = double(L[c]);
            const double delta = xv - mean[c];
            mean[c] += delta / double(s + 1);
            m2[c] += delta * (xv - mean[c]);
          }
        }
      }
      const size_t i = size_t(y - rect.y0) * size_t(rect.width) + size_t(x - rect.x0);
      double var = 0;
      for (int c = 0; c < 3; ++c) {
        out.rgb[3 * i + size_t(c)] = float(mean[c]);
        if (spp > 1) var += m2[c] / double(spp - 1) / double(spp);
      }
      out.variance[i] = float(var / 3.0);
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

void place_tile(const TileResult& tile, ImageRGB* image, std::vector<float>* variance) {
  const TileRect& r = tile.rect;
  for (int y = 0; y < r.height; ++y) {
    const size_t src = size_t(y) * size_t(r.width);
    std::copy_n(&tile.rgb[3 * src], 3 * size_t(r.width), image->at(r.x0, r.y0 + y));
    if (variance) {
      std::copy_n(&tile.variance[src], size_t(r.width),
                  &(*variance)[size_t(r.y0 + y) * size_t(image->width) + size_t(r.x0)]);
    }
  }
}

FrameResult render_frame(const RenderScene& scene, int tile_size, int threads,
                         const std::function<void(int, int)>& progress) {
  const auto start = std::chrono::steady_clock::now();
  const ImageSettings& img = scene.image();
  FrameResult out;
  out.image = ImageRGB(img.width, img.height);
  out.variance.assign(out.image.pixel_count(), 0.0f);
  const std::vector<TileRect> tiles = split_into_tiles(img.width, img.height, tile_size);
  std::mutex mutex;
  std::atomic<int> done{0};
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), tiles.size(), [&](size_t i) {
      const TileResult t = render_tile(scene, tiles[i]);
      std::lock_guard lock(mutex);
      place_tile(t, &out.image, &out.variance);
      out.rays += t.rays;
      if (progress) progress(++done, int(tiles.size()));
    });
  });
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "render/pixel_samples.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/integrator.h"
#include "render/isa_clones.h"
#include "render/ray_lanes.h"
#include "tile/bfloat16.h"

namespace tessera {

namespace {

// The pixels of a rectangle, row-major, each with samples [from, to).
class RectPixels {
 public:
  RectPixels(const TileRect& r, uint32_t from, uint32_t to, PixelEstimate* est)
      : r_(r), from_(from), to_(to), x_(r.x0), y_(r.y0), e_(est) {}
  bool valid() const { return y_ < r_.y0 + r_.height; }
  int x() const { return x_; }
  int y() const { return y_; }
  uint32_t from() const { return from_; }
  uint32_t to() const { return to_; }
  PixelEstimate* est() const { return e_; }
  void next() {
    ++e_;
    if (++x_ == r_.x0 + r_.width) x_ = r_.x0, ++y_;
  }

 private:
  TileRect r_;
  uint32_t from_, to_;
  int x_, y_;
  PixelEstimate* e_;
};

// A list of pixel runs, in order.
class RunPixels {
 public:
  RunPixels(const PixelRun* runs, size_t n) : r_(runs), end_(runs + n) {}
  bool valid() const { return r_ != end_; }
  int x() const { return r_->x; }
  int y() const { return r_->y; }
  uint32_t from() const { return r_->from; }
  uint32_t to() const { return r_->to; }
  PixelEstimate* est() const { return r_->est; }
  void next() { ++r_; }

 private:
  const PixelRun* r_;
  const PixelRun* end_;
};

// Renders the samples of every pixel `pixels` visits (each with from < to), in that order.
template <class Pixels>
[[gnu::always_inline]] inline void render_pixels(const RenderScene& scene, Pixels pixels, RayCounts* rays) {
  constexpr int P = RenderScene::kPacket;
  if (!pixels.valid()) return;
  const ImageSettings& img = scene.image();
  // The lattice sampler's edge pixels take the default sampler's samples, bit for bit
  // (render/lattice_sampler.h).
  const SamplerKind kind = img.sampler == SamplerKind::kLattice ? SamplerKind::kSobol : img.sampler;
  const auto& cam = scene.camera();
  // The next sample to set up: the pixel `pixels` is at, sample `s`; its camera sampler is made
  // once per pixel (the pixel's key and the scramble seeds are most of a sample's hashing).
  uint32_t s = pixels.from();
  uint64_t key = PixelSampler::pixel_key(img.seed, scene.frame(), pixels.x(), pixels.y());
  CameraSampler camera(kind, key, uint32_t(img.spp));
  static_assert(P == kOwenLanes);
  const bool sobol_lanes = kind == SamplerKind::kSobol;
  PixelSampler samplers[P];
  PixelEstimate* lane_est[P];
  uint32_t lane_sample[P];
  // Made once, not per packet: lanes past a packet's n keep finite values from earlier packets
  // (zeros at first), computed on and never traced. Zero-filling them per packet was a tenth of
  // this function's time (perf annotate: `rep stos`).
  alignas(32) float su[P] = {}, sv[P] = {}, fx[P] = {}, fy[P] = {};
  OwenSobolLanes sobol = {};
  RayLanes r;  // camera rays: origin 0, tmax infinite
  std::fill(r.tmax, r.tmax + P, std::numeric_limits<float>::infinity());
  while (pixels.valid()) {
    // One packet: the next P samples in (pixel, sample) order, across pixels when a pixel has
    // fewer samples left than lanes, so packets stay full at low sample counts. A lane's result
    // depends only on its own ray and sampler (integrator.h), so how samples share packets
    // changes no bit; the estimates still take each pixel's samples in sample order.
    int n = 0;
    for (; n < P && pixels.valid(); ++n) {
      samplers[n] = PixelSampler(kind, key, s, uint32_t(img.spp));
      if (sobol_lanes) {
        const OwenSeeds& seeds = camera.seeds(s);
        sobol.index[n] = stream_index(s);
        sobol.seed_index[n] = seeds.index, sobol.seed_x[n] = seeds.x, sobol.seed_y[n] = seeds.y;
      } else {
        camera.pixel_offset(s, &su[n], &sv[n]);
      }
      fx[n] = float(pixels.x());
      fy[n] = float(pixels.y());
      lane_est[n] = pixels.est();
      lane_sample[n] = s;
      if (++s < pixels.to()) continue;
      // The pixel's last sample: on to the next pixel.
      pixels.next();
      if (pixels.valid()) {
        s = pixels.from();
        key = PixelSampler::pixel_key(img.seed, scene.frame(), pixels.x(), pixels.y());
        camera = CameraSampler(kind, key, uint32_t(img.spp));
      }
    }
    // The default sampler's pixel positions for all lanes at once (render/sampler.h); lanes past
    // n compute on zeros and are never traced.
    if (sobol_lanes) owen_sobol_2d_lanes(sobol, su, sv);
    // Camera rays for all P lanes at once (a fixed trip count the compiler vectorizes: its
    // divisions and square roots were a sixth of a primary-ray-bound frame). The arithmetic per
    // lane is the scalar normalize(p0 + du u + dv v), operation for operation.
    // The directions go straight into the packet's arrays (render/ray_lanes.h).
    for (int i = 0; i < P; ++i) {
      const float u = (fx[i] + su[i]) / float(img.width);
      const float v = (fy[i] + sv[i]) / float(img.height);
      set_camera_direction(cam, u, v, &r, i);
    }
    Rgb Ls[P];
    rays->camera += uint64_t(n);
    trace_radiance_packet(scene, r, samplers, n, rays, Ls);
    for (int i = 0; i < n; ++i) {
      Rgb L = Ls[i];
      if (!is_finite(L)) {
        ++rays->nonfinite_samples;  // never let NaN/Inf reach a pixel; counted, not hidden
        L = Rgb(0.0f);
      }
      lane_est[i]->add(lane_sample[i], L);
    }
  }
}

}  // namespace

// Compiled for AVX2 and the baseline (render/isa_clones.h): its per-lane set-up and camera rays are
// plain C++ the compiler vectorizes.
TESSERA_ISA_CLONES void render_samples(const RenderScene& scene, const TileRect& pixels, uint32_t from, uint32_t to,
                                       PixelEstimate* est, RayCounts* rays) {
  if (to <= from || pixels.width <= 0 || pixels.height <= 0) return;
  render_pixels(scene, RectPixels(pixels, from, to, est), rays);
}

TESSERA_ISA_CLONES void render_pixel_runs(const RenderScene& scene, const PixelRun* runs, size_t n, RayCounts* rays) {
  render_pixels(scene, RunPixels(runs, n), rays);
}

void store_pixel(const PixelEstimate& est, SamplerKind kind, size_t i, TileResult* out) {
  for (int c = 0; c < 3; ++c) out->rgb[3 * i + size_t(c)] = est.mean(c);
  // Kept at the precision tiles carry it at (tile/bfloat16.h): a farm's frames and their error
  // report are then bit-identical to an in-process render's.
  out->variance[i] = round_to_bfloat16(float(est.variance(kind)));
  out->spp[i] = est.samples();
}

}  // namespace tessera

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

// Compiled for AVX2 and the baseline (render/isa_clones.h): its per-lane set-up and camera rays are
// plain C++ the compiler vectorizes.
TESSERA_ISA_CLONES void render_samples(const RenderScene& scene, const TileRect& pixels, uint32_t from, uint32_t to,
                                       PixelEstimate* est, RayCounts* rays) {
  constexpr int P = RenderScene::kPacket;
  if (to <= from || pixels.width <= 0 || pixels.height <= 0) return;
  const ImageSettings& img = scene.image();
  // The lattice sampler's edge pixels take the default sampler's samples, bit for bit
  // (render/lattice_sampler.h).
  const SamplerKind kind = img.sampler == SamplerKind::kLattice ? SamplerKind::kSobol : img.sampler;
  const auto& cam = scene.camera();
  // The next sample to set up: pixel (x, y), sample `s`, the pixel's estimate `e`; its camera
  // sampler is made once per pixel (the pixel's key and the scramble seeds are most of a
  // sample's hashing).
  int x = pixels.x0, y = pixels.y0;
  uint32_t s = from;
  PixelEstimate* e = est;
  uint64_t key = PixelSampler::pixel_key(img.seed, scene.frame(), x, y);
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
  while (y < pixels.y0 + pixels.height) {
    // One packet: the next P samples in (pixel, sample) order, across pixels when a pixel has
    // fewer samples left than lanes, so packets stay full at low sample counts. A lane's result
    // depends only on its own ray and sampler (integrator.h), so how samples share packets
    // changes no bit; the estimates still take each pixel's samples in sample order.
    int n = 0;
    for (; n < P && y < pixels.y0 + pixels.height; ++n) {
      samplers[n] = PixelSampler(kind, key, s, uint32_t(img.spp));
      if (sobol_lanes) {
        const OwenSeeds& seeds = camera.seeds(s);
        sobol.index[n] = stream_index(s);
        sobol.seed_index[n] = seeds.index, sobol.seed_x[n] = seeds.x, sobol.seed_y[n] = seeds.y;
      } else {
        camera.pixel_offset(s, &su[n], &sv[n]);
      }
      fx[n] = float(x);
      fy[n] = float(y);
      lane_est[n] = e;
      lane_sample[n] = s;
      if (++s < to) continue;
      // The pixel's last sample: on to the next pixel, row-major.
      s = from;
      ++e;
      if (++x == pixels.x0 + pixels.width) x = pixels.x0, ++y;
      if (y < pixels.y0 + pixels.height) {
        key = PixelSampler::pixel_key(img.seed, scene.frame(), x, y);
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

void store_pixel(const PixelEstimate& est, SamplerKind kind, size_t i, TileResult* out) {
  for (int c = 0; c < 3; ++c) out->rgb[3 * i + size_t(c)] = est.mean(c);
  // Kept at the precision tiles carry it at (tile/bfloat16.h): a farm's frames and their error
  // report are then bit-identical to an in-process render's.
  out->variance[i] = round_to_bfloat16(float(est.variance(kind)));
  out->spp[i] = est.samples();
}

}  // namespace tessera

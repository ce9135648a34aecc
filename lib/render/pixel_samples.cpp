#include "render/pixel_samples.h"

#include <algorithm>
#include <cmath>

#include "render/integrator.h"
#include "tile/bfloat16.h"

namespace tessera {

void render_samples(const RenderScene& scene, int x, int y, uint32_t from, uint32_t to, PixelEstimate* est,
                    RayCounts* rays) {
  const ImageSettings& img = scene.image();
  const auto& cam = scene.camera();
  PixelSampler samplers[RenderScene::kPacket];
  const uint64_t pixel_key = PixelSampler::pixel_key(img.seed, scene.frame(), x, y);
  const CameraSampler camera(img.sampler, pixel_key, uint32_t(img.spp));
  for (uint32_t s0 = from; s0 < to;) {
    const uint32_t packet_end = std::min<uint32_t>(to, (s0 / RenderScene::kPacket + 1) * RenderScene::kPacket);
    const int n = int(packet_end - s0);
    Ray r[RenderScene::kPacket];
    Rgb Ls[RenderScene::kPacket];
    // Camera rays in two passes: the sampler's integer hashing per lane, then the directions for
    // all kPacket lanes at once (a fixed trip count the compiler vectorizes: its divisions and
    // square roots were a sixth of a primary-ray-bound frame). The arithmetic per lane is the
    // scalar normalize(p0 + du u + dv v), operation for operation.
    alignas(32) float su[RenderScene::kPacket] = {}, sv[RenderScene::kPacket] = {};
    for (int i = 0; i < n; ++i) {
      samplers[i] = PixelSampler(img.sampler, pixel_key, s0 + uint32_t(i), uint32_t(img.spp));
      camera.pixel_offset(s0 + uint32_t(i), &su[i], &sv[i]);
    }
    alignas(32) float dx[RenderScene::kPacket], dy[RenderScene::kPacket], dz[RenderScene::kPacket];
    for (int i = 0; i < RenderScene::kPacket; ++i) {
      const float u = (float(x) + su[i]) / float(img.width);
      const float v = (float(y) + sv[i]) / float(img.height);
      const float px = cam.p0.x + cam.du.x * u + cam.dv.x * v;
      const float py = cam.p0.y + cam.du.y * u + cam.dv.y * v;
      const float pz = cam.p0.z + cam.du.z * u + cam.dv.z * v;
      const float len = std::sqrt(px * px + py * py + pz * pz);
      dx[i] = px / len;
      dy[i] = py / len;
      dz[i] = pz / len;
    }
    for (int i = 0; i < n; ++i) r[i] = {Vec3f(0.0f), Vec3f(dx[i], dy[i], dz[i])};
    rays->camera += uint64_t(n);
    trace_radiance_packet(scene, r, samplers, n, rays, Ls);
    for (int i = 0; i < n; ++i) {
      Rgb L = Ls[i];
      if (!is_finite(L)) {
        ++rays->nonfinite_samples;  // never let NaN/Inf reach a pixel; counted, not hidden
        L = Rgb(0.0f);
      }
      est->add(s0 + uint32_t(i), L);
    }
    s0 = packet_end;
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

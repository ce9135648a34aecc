// The textures of diffuse materials at a hit: an image texture's albedo (by the hit's uv) and
// the checker pattern's parity.
#include <bit>
#include <cmath>
#include <cstdint>

#include "render/render_scene.h"
#include "scene/texture_sample.h"

namespace tessera {

Rgb RenderScene::textured_albedo(const Hit& hit, const Material& m) const {
  const auto& t = m.uv_transform;
  const double u = t[0] * hit.tex_u + t[1] * hit.tex_v + t[2], v = t[3] * hit.tex_u + t[4] * hit.tex_v + t[5];
  return m.albedo * sample_texture(textures_[size_t(m.albedo_texture)], u, v);
}

// The checker's coordinate x / s is taken as x * (1 / s) where s is a power of two: the
// reciprocal 2^-k is then exact and x * 2^-k is the same real number as x / 2^k, rounded once
// either way, so the bits are the division's; the divisions were two thirds of the checker's time
// on the Whitted showcase (perf annotate), whose scale is 1. Returns 1 / s for such an s (positive,
// normal, no mantissa bits, its reciprocal normal too), else 0: divide.
double RenderScene::checker_inverse(double scale) {
  const uint64_t bits = std::bit_cast<uint64_t>(scale);
  const uint64_t e = (bits >> 52) & 0x7ff;
  if ((bits >> 63) == 0 && (bits & ((uint64_t(1) << 52) - 1)) == 0 && e >= 1 && e <= 2045) {
    return std::bit_cast<double>((2046 - e) << 52);
  }
  return 0.0;
}

int RenderScene::checker_parity(const Hit& hit, const Material& m) const {
  // x / scale, by the reciprocal made at build time where that gives the same bits.
  const double inv = checker_inverse_[hit.material], scale = m.checker_scale;
  const auto of = [inv, scale](double x) { return inv != 0 ? x * inv : x / scale; };
  if (hit.prim.kind == PrimRef::Kind::kPlane) {
    // 2D squares in the plane's own basis, anchored at its point: independent of where the
    // plane is in the world.
    const Plane& pl = planes_[hit.prim.id];
    const Vec3d rel = Vec3d(hit.p) - pl.point;
    const double a = std::floor(of(dot(rel, pl.b1))), b = std::floor(of(dot(rel, pl.b2)));
    return int(int64_t(a + b) & 1);
  }
  const Vec3d w = Vec3d(hit.p) + origin_;  // solid 3D checker in world space
  const double sum = std::floor(of(w.x)) + std::floor(of(w.y)) + std::floor(of(w.z));
  return int(int64_t(sum) & 1);
}

}  // namespace tessera

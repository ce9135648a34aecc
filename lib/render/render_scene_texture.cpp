// The textures of diffuse materials at a hit: an image texture's albedo (by the hit's uv) and
// the checker pattern's parity.
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

int RenderScene::checker_parity(const Hit& hit, const Material& m) const {
  const double s = m.checker_scale;
  if (hit.prim.kind == PrimRef::Kind::kPlane) {
    // 2D squares in the plane's own basis, anchored at its point: independent of where the
    // plane is in the world.
    const Plane& pl = planes_[hit.prim.id];
    const Vec3d rel = Vec3d(hit.p) - pl.point;
    const double a = std::floor(dot(rel, Vec3d(pl.b1)) / s), b = std::floor(dot(rel, Vec3d(pl.b2)) / s);
    return int(int64_t(a + b) & 1);
  }
  const Vec3d w = Vec3d(hit.p) + origin_;  // solid 3D checker in world space
  const double sum = std::floor(w.x / s) + std::floor(w.y / s) + std::floor(w.z / s);
  return int(int64_t(sum) & 1);
}

}  // namespace tessera

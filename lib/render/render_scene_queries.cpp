// SPDX-License-Identifier: Apache-2.0
// render/render_scene.h's functions: each is the RenderScene member of the same name, so that
// the programs and lib/rays can build a frame and ask it these queries without the class (and
// its packet and ISA-cloned internals) in view.
#include "render/render_scene.h"

#include "render/render_scene_internal.h"

namespace tessera {

std::shared_ptr<const RenderScene> make_render_scene(const Scene& scene, int frame, RenderOptions options) {
  return std::make_shared<const RenderScene>(scene, frame, options);
}

const ImageSettings& image_settings(const RenderScene& scene) { return scene.image(); }
Vec3d render_origin(const RenderScene& scene) { return scene.origin(); }
float bounds_radius(const RenderScene& scene) { return scene.bounds_radius(); }
size_t triangle_count(const RenderScene& scene) { return scene.triangle_count(); }
PrimSource source_of(const RenderScene& scene, const PrimRef& prim) { return scene.source_of(prim); }

bool intersect(const RenderScene& scene, const Ray& ray, const PrimRef& from, Hit* hit) {
  return scene.intersect(ray, from, hit);
}
bool any_hit(const RenderScene& scene, const Ray& ray, const PrimRef& from) { return scene.any_hit(ray, from); }
void intersect_batch(const RenderScene& scene, const RayBatch& rays, size_t n, HitBatch* hits) {
  scene.intersect_batch(rays, n, hits);
}
void any_hit_batch(const RenderScene& scene, const RayBatch& rays, size_t n, uint8_t* blocked) {
  scene.any_hit_batch(rays, n, blocked);
}

}  // namespace tessera

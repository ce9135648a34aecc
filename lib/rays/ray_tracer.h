// SPDX-License-Identifier: Apache-2.0
// Nearest-hit and occlusion queries for world-space rays on one frame of a scene, answered by
// the RenderScene's intersect() (render/render_scene.h): the renderer's own code (watertight
// triangles, double-precision spheres and planes, the renderer's tie-breaking), so a query's
// hit is the one the renderer would find. Knows nothing of gRPC or files.
#pragma once

#include <cstddef>
#include <memory>

#include "rays/world_ray.h"
#include "render/render_scene.h"
#include "scene/scene.h"

namespace tessera::rays {

class RayTracer {
 public:
  // `frame` must have been built from `scene`.
  RayTracer(std::shared_ptr<const Scene> scene, std::shared_ptr<const RenderScene> frame);

  // Both trace n rays that passed check_ray() (not checked again here), each with its own
  // Embree query, so a ray's answer depends on that ray alone, never on the batch around it. Const and thread-safe: any
  // number of threads may trace at once.
  void nearest(const WorldRay* rays, size_t n, WorldHit* hits) const;
  // The same answers written into arrays (world_ray.h), ray i's at index `offset + i`: what the
  // ray service sends, without the copy through WorldHit.
  void nearest_into(const WorldRay* rays, size_t n, const HitColumns& out, size_t offset) const;
  // Sets only hits[i].hit: whether any surface lies in (tmin, tmax], by an any-hit traversal
  // (any_hit(), render/render_scene.h: it stops at the first surface met) of the same
  // render-space rays with the same primitive tests, so "occluded" and "has a nearest hit" never
  // disagree.
  void occluded(const WorldRay* rays, size_t n, WorldHit* hits) const;

  const Scene& scene() const { return *scene_; }
  const RenderScene& frame() const { return *frame_; }

 private:
  // The render-space rays a world ray becomes (query() in the .cpp says why): for a far origin,
  // `before` (up to where it enters the geometry's cube) and then `after`; else `after` alone.
  struct Query {
    Vec3d dd;                  // unit direction, double
    double shift = 0;          // t of before's start (t_min)
    double after_shift = 0;    // t of after's start
    Ray before, after;
    bool has_before = false;
  };
  Query query(const WorldRay& ray) const;
  // Where a ray's start counts as far (max norm, render space): 16x the radius of all bounded
  // geometry, the renderer's own threshold; query() moves such a start.
  double far_limit() const { return 16.0 * double(bounds_radius_); }
  bool trace(const WorldRay& ray, WorldHit* hit) const;
  // The world-space answer for a render-space hit on a ray that started `shift` along the query.
  bool to_world(const Hit& h, double shift, const Vec3f& d, WorldHit* out) const;
  bool blocked(const WorldRay& ray) const;
  // nearest()'s work, answers given to `emit`: emit.batch(base, answers, m) for rays [base,
  // base + m) of a SIMD batch (every lane, a miss's defaults where the batch did not answer), then
  // emit.scalar(i, hit) for each ray of it the scalar code answered (hit.hit false for a miss).
  template <class Emit>
  void nearest_each(const WorldRay* rays, size_t n, Emit& emit) const;

  std::shared_ptr<const Scene> scene_;
  std::shared_ptr<const RenderScene> frame_;
  // The frame's render_origin() and bounds_radius(), read on every ray: kept here, not asked.
  Vec3d origin_;
  float bounds_radius_;
};

}  // namespace tessera::rays

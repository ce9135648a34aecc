// SPDX-License-Identifier: Apache-2.0
// A frame of a Scene built for tracing, as the programs and lib/rays see it. It is built once
// per frame (make_render_scene) and then shared read-only by any number of threads: the renderer
// takes it whole (render_tile, render_frame: render/tile_renderer.h), and the ray service asks
// it the queries below, which are the renderer's own intersection code, so a ray query is
// answered exactly as a render would trace that ray.
//
// What a RenderScene is made of (the Embree scene, the lights and materials as the integrator
// reads them, the packet and ISA-cloned variants of the queries) is lib/render's own:
// render/render_scene_internal.h, which nothing outside lib/render includes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "math/vec3.h"
#include "render/hit.h"
#include "render/ray.h"
#include "render/render_options.h"
#include "scene/scene.h"

namespace tessera {

class RenderScene;
struct RayBatch;
struct HitBatch;

// Frame `frame` of `scene`, built: camera-relative float geometry in an Embree scene, infinite
// planes beside it, lights and materials. Needs the Embree device (render/embree_device.h).
std::shared_ptr<const RenderScene> make_render_scene(const Scene& scene, int frame, RenderOptions options = {});

// Where a primitive came from: its object (index into Scene::objects) and, for meshes, the
// triangle's index in the mesh file (0 for spheres and planes).
struct PrimSource {
  uint32_t object = UINT32_MAX, primitive = 0;
};

// The image settings of the frame (its size, samples, frame target).
const ImageSettings& image_settings(const RenderScene& scene);
// World position of render space's origin (the eye): render-space points are relative to it.
Vec3d render_origin(const RenderScene& scene);
// Max |coordinate| of all bounded geometry (triangles, spheres), render space: the ray service
// moves far ray origins to this cube's neighbourhood in double before rounding them to float.
float bounds_radius(const RenderScene& scene);
size_t triangle_count(const RenderScene& scene);
PrimSource source_of(const RenderScene& scene, const PrimRef& prim);

// Nearest hit along the ray in (0, ray.tmax]; `from` is the primitive the ray leaves.
bool intersect(const RenderScene& scene, const Ray& ray, const PrimRef& from, Hit* hit);
// Whether intersect() would find a hit with a finite point, by an any-hit traversal that stops
// at the first surface met, glass included: line-of-sight queries.
bool any_hit(const RenderScene& scene, const Ray& ray, const PrimRef& from);
// intersect() and any_hit() of n <= kRayBatch rays from no surface, as arrays of components
// (render/ray_batch.h), bit for bit the single-ray answers: the ray service's batches.
// blocked[i] = 1 or 0; lanes with skip set are left as they are.
void intersect_batch(const RenderScene& scene, const RayBatch& rays, size_t n, HitBatch* hits);
void any_hit_batch(const RenderScene& scene, const RayBatch& rays, size_t n, uint8_t* blocked);

}  // namespace tessera

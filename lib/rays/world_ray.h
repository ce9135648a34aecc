// SPDX-License-Identifier: Apache-2.0
// A ray query and its answer in world space, as the ray service's clients see them (the
// renderer works in camera-relative float space; RayTracer converts).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>

#include "math/vec3.h"

namespace tessera::rays {

inline constexpr uint32_t kNoIndex = UINT32_MAX;

struct WorldRay {
  Vec3d o;        // world space, double: a far origin keeps its precision
  Vec3d d;        // any nonzero length; t is distance along d / |d|. Double: a far origin's
                  // ray would otherwise bend by |o| * 2^-24 before it reaches anything
  float tmin = 0.0f;
  float tmax = std::numeric_limits<float>::infinity();
};

struct WorldHit {
  bool hit = false;  // nearest-hit queries: found a surface; occlusion queries: blocked
  float t = std::numeric_limits<float>::infinity();
  Vec3d p;           // on the surface (recomputed there, not o + t d), world space
  Vec3f n;           // unit geometric normal
  Vec3f ns;          // the normal the renderer shades with, facing the ray (a mesh's interpolated vertex normals, else n)
  float u = 0, v = 0;  // triangle barycentrics
  uint32_t object = kNoIndex;     // index into Scene::objects
  uint32_t primitive = kNoIndex;  // triangle index in its mesh; 0 for spheres and planes
  uint32_t material = kNoIndex;   // index into Scene::materials
};

// Where RayTracer::nearest_into() writes answers: arrays laid out as the ray service's response
// (tessera.v1.TraceResponse), so a batch goes there without a WorldHit in between. Ray i's
// values go to index i (times the values a ray): hit 1 byte (1 or 0); t; p 3 doubles; n and ns
// 3 floats; uv 2 floats (u, v); object, primitive, material. A null array is not written.
struct HitColumns {
  char* hit = nullptr;
  float* t = nullptr;
  double* p = nullptr;
  float* n = nullptr;
  float* ns = nullptr;
  float* uv = nullptr;
  uint32_t* object = nullptr;
  uint32_t* primitive = nullptr;
  uint32_t* material = nullptr;
};

// Writes one answer into the given arrays at index k (a null array is skipped).
inline void write_hit(const HitColumns& c, size_t k, const WorldHit& h) {
  if (c.hit) c.hit[k] = h.hit ? 1 : 0;
  if (c.t) c.t[k] = h.t;
  for (int q = 0; q < 3; ++q) {
    if (c.p) c.p[3 * k + q] = h.p[q];
    if (c.n) c.n[3 * k + q] = h.n[q];
    if (c.ns) c.ns[3 * k + q] = h.ns[q];
  }
  if (c.uv) c.uv[2 * k] = h.u, c.uv[2 * k + 1] = h.v;
  if (c.object) c.object[k] = h.object;
  if (c.primitive) c.primitive[k] = h.primitive;
  if (c.material) c.material[k] = h.material;
}

}  // namespace tessera::rays

// A ray query and its answer in world space, as the ray service's clients see them (the
// renderer works in camera-relative float space; RayTracer converts).
#pragma once

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

}  // namespace tessera::rays

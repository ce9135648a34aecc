// SPDX-License-Identifier: Apache-2.0
// What a ray meets: the primitive (PrimRef) and the surface point there (Hit), in render space.
#pragma once

#include <cstdint>

#include "math/vec3.h"

namespace tessera {

// Identifies the primitive a ray leaves from, so flat and convex primitives can exclude
// themselves exactly instead of relying on an epsilon.
struct PrimRef {
  enum class Kind : uint8_t { kNone, kTriangle, kSphere, kPlane };
  Kind kind = Kind::kNone;
  uint32_t id = 0;  // triangle index within its geometry bucket, sphere index, plane index
  uint32_t geom = 0;
  bool operator==(const PrimRef&) const = default;
};

struct Hit {
  float t = 0;
  Vec3f p;       // the hit point, recomputed on the surface (not o + t d)
  Vec3f p_err;   // conservative absolute error bound of p, per component
  Vec3f n;       // unit geometric normal: outward for spheres, winding (CCW) for triangles
  uint32_t material = 0;
  PrimRef prim;
  // Barycentrics of a triangle hit: p = (1-u-v) v0 + u v1 + v v2 (the values p was computed
  // from); 0 for spheres and planes. Read by the ray service (lib/rays), not by shading.
  float u = 0, v = 0;
  float tex_u = 0, tex_v = 0;  // texture coordinates (triangles of textured materials only)
  // Interpolated unit shading normal (render/shading_normal.h), on n's side; set only where
  // `smooth` (triangles with vertex normals): read it only then.
  Vec3f ns;
  bool smooth = false;
};

}  // namespace tessera

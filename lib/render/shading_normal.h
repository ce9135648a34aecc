// SPDX-License-Identifier: Apache-2.0
// Interpolated shading normals for meshes that carry vertex normals (glTF NORMAL), and the rules
// that keep them from breaking light transport. The geometric normal still decides everything
// about *where* a ray is: which side a hit is seen from, where secondary and shadow rays start
// (offset_ray_origin) and whether a light is above the surface at all. The shading normal only
// changes *how* light is weighted and which way mirrors and glass send rays:
//  - Direct light: cos(theta) is taken from the shading normal, times Chiang, Li and Burley's
//    terminator term ("Taming the Shadow Terminator", SIGGRAPH 2019 talk), which fades the light
//    smoothly to 0 where the geometric surface turns away from it. Without it a coarse sphere's
//    terminator is a staircase of facets: the shading normal says "lit", the facet says "in its
//    own shadow". A light below the geometric surface gives nothing (the facet blocks it).
//  - Mirror and glass: reflect and refract about the shading normal; a reflected ray that would
//    leave below the geometric surface (or a refracted ray above it) is mirrored about the
//    geometric tangent plane, which is continuous where the two agree and never sends a ray
//    into the surface it leaves. Where the viewer is behind the shading normal's hemisphere
//    (grazing views of a strongly bent normal), the geometric normal is used for that hit.
// Triangles without vertex normals (OBJ, PLY, glTF without NORMAL) take none of these paths, so
// their pixels are bit-identical to a renderer without shading normals.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

#include "math/vec3.h"

namespace tessera {

// Appends triangle `triangle`'s three unit vertex normals (render space) to `normals`, 9 floats
// a triangle; triangles before it that had none get zeros (flat). A zero, non-finite or
// unnormalizable vertex normal makes the whole triangle flat: a shading normal needs all three.
inline void append_vertex_normals(std::vector<float>* normals, size_t triangle, const std::array<Vec3d, 3>& n) {
  normals->resize(9 * triangle, 0.0f);
  std::array<Vec3f, 3> unit{};
  bool ok = true;
  for (int k = 0; k < 3; ++k) {
    const double len = length(n[k]);
    ok = ok && std::isfinite(len) && len > 0;
    if (ok) unit[k] = Vec3f(n[k] / len);
  }
  for (int k = 0; k < 3; ++k) {
    const Vec3f v = ok ? unit[k] : Vec3f(0.0f);
    normals->insert(normals->end(), {v.x, v.y, v.z});
  }
}

// The shading normal at barycentrics (w, u, v) of a triangle whose 9 floats `n9` were appended
// above, turned to the geometric normal's side (the winding decides the side; a file's normals
// only bend it). False, and *ns untouched, for flat triangles or where the interpolation
// cancels out (opposite vertex normals).
inline bool interpolate_shading_normal(const float* n9, float w, float u, float v, const Vec3f& ng, Vec3f* ns) {
  const Vec3f n0(n9[0], n9[1], n9[2]), n1(n9[3], n9[4], n9[5]), n2(n9[6], n9[7], n9[8]);
  const Vec3f s = n0 * w + n1 * u + n2 * v;
  const float len = length(s);
  if (!(len > 1e-6f)) return false;  // flat (all zero) or cancelled
  const Vec3f unit = s / len;
  *ns = dot(unit, ng) < 0.0f ? -unit : unit;
  return true;
}

// The shading normal on the side of `ng_facing` (the geometric normal turned towards the viewer).
inline Vec3f facing(const Vec3f& ns, const Vec3f& ng, const Vec3f& ng_facing) {
  return dot(ng, ng_facing) > 0.0f ? ns : -ns;
}

// The weight cos(theta) of light arriving from unit direction w at a smooth point: the shading
// normal's cosine times the terminator term G' = -G^3 + G^2 + G, G = min(1, (ng.w) / ((ns.w)(ng.ns))).
// 0 where w is below the geometric or the shading surface.
inline float smooth_light_cosine(const Vec3f& ng_facing, const Vec3f& ns_facing, const Vec3f& w) {
  const float cos_g = dot(ng_facing, w), cos_s = dot(ns_facing, w);
  if (!(cos_g > 0.0f) || !(cos_s > 0.0f)) return 0.0f;
  const float g = std::fmin(1.0f, cos_g / (cos_s * dot(ng_facing, ns_facing)));
  return cos_s * (g + g * g - g * g * g);
}

// The normal mirrors and glass turn rays about at a smooth point seen along d: the shading
// normal, unless d meets it from behind (then the geometric one).
inline Vec3f turning_normal(const Vec3f& ng_facing, const Vec3f& ns_facing, const Vec3f& d) {
  return dot(d, ns_facing) < 0.0f ? ns_facing : ng_facing;
}

// w, mirrored about the geometric tangent plane when it is on the wrong side of it: above
// (`above` true: reflections) or below (refractions). A direction exactly in the plane falls
// back to `fallback` (the geometric normal's reflection or refraction).
inline Vec3f keep_side(const Vec3f& w, const Vec3f& ng_facing, bool above, const Vec3f& fallback) {
  const float c = dot(w, ng_facing);
  if (above ? c > 0.0f : c < 0.0f) return w;
  const Vec3f m = normalize(w - ng_facing * (2.0f * c));
  const float cm = dot(m, ng_facing);
  return (above ? cm > 0.0f : cm < 0.0f) ? m : fallback;
}

}  // namespace tessera

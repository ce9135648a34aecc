// SPDX-License-Identifier: Apache-2.0
// Watertight ray/triangle intersection (Woop, Benthin, Wald, "Watertight Ray/Triangle
// Intersection", JCGT 2(1), 2013), with the edge functions evaluated in double.
//
// Why not Embree's own test: Embree 3.13.5's robust mode (RTC_SCENE_FLAG_ROBUST) is a Pluecker
// test with a 1-ulp tolerance. Along a shared edge both triangles evaluate the same edge
// function, so edges are closed; at a shared vertex the rounding noise of the edge functions is
// ~40x that tolerance, and a ray aimed at the vertex can be rejected by every triangle of the fan
// (measured: 1199 of 81,936 such rays on an icosphere; docs/accuracy.md, case 4).
//
// Why this test is watertight: every vertex is translated to the ray origin and sheared so the
// ray becomes the +z axis, by the same float operations whatever triangle the vertex belongs to,
// so a vertex shared by several triangles gets bit-identical 2D coordinates in all of them. Each
// edge function U = x_c y_b - y_c x_b is then formed in double, where the products of two floats
// are exact and the one subtraction is correctly rounded: its sign is the exact orientation of
// the projected points. So the two triangles of an edge see the ray on exactly opposite sides of
// it (or both exactly on it), and around a vertex the fan's exact orientations tile the plane: a
// ray through a closed mesh's projection is accepted by at least one triangle, boundaries
// included. Woop et al. evaluate in float and fall back to double only when an edge function is
// exactly 0. Float signs are still antisymmetric across an edge (rounding is symmetric), but can
// be wrong when the ray is nearly parallel to a projected edge, which turns the vertex argument
// from a proof into a near-certainty; double makes it exact for a few more cycles. The shear must
// be the same float operations for every copy of a vertex: the project builds with
// -ffp-contract=off, so no FMA contracts it differently in different places.
#pragma once

#include <cmath>
#include <utility>

#include "math/vec3.h"

namespace tessera {

// The ray's shear, shared by all triangles one ray is tested against: the dominant axis of d
// becomes z; x and y are swapped when d_z < 0 so the winding (and so the sign of det) is kept.
struct RayShear {
  int kx, ky, kz;
  float sx, sy, sz;
};

inline RayShear ray_shear(const Vec3f& d) {
  const float ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
  const int kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
  int kx = kz == 2 ? 0 : kz + 1, ky = kx == 2 ? 0 : kx + 1;
  if (d[kz] < 0.0f) std::swap(kx, ky);
  return {kx, ky, kz, d[kx] / d[kz], d[ky] / d[kz], 1.0f / d[kz]};
}

struct TriangleHit {
  float t;     // distance along the ray (|d| = 1)
  float u, v;  // barycentric weights of the second and third vertex (Embree's convention)
};

// Intersects the ray o + t d with triangle (a, b, c), either side, boundaries included, for
// t in [tnear, tfar]. Returns false on a miss, a degenerate (zero projected area) triangle, or
// non-finite arithmetic.
inline bool intersect_triangle_watertight(const Vec3f& o, const RayShear& s, const Vec3f& a, const Vec3f& b,
                                          const Vec3f& c, float tnear, float tfar, TriangleHit* hit) {
  const Vec3f A = a - o, B = b - o, C = c - o;
  const float ax = A[s.kx] - s.sx * A[s.kz], ay = A[s.ky] - s.sy * A[s.kz];
  const float bx = B[s.kx] - s.sx * B[s.kz], by = B[s.ky] - s.sy * B[s.kz];
  const float cx = C[s.kx] - s.sx * C[s.kz], cy = C[s.ky] - s.sy * C[s.kz];
  const double U = double(cx) * double(by) - double(cy) * double(bx);
  const double V = double(ax) * double(cy) - double(ay) * double(cx);
  const double W = double(bx) * double(ay) - double(by) * double(ax);
  if ((U < 0 || V < 0 || W < 0) && (U > 0 || V > 0 || W > 0)) return false;
  const double det = U + V + W;
  if (det == 0) return false;
  const double az = double(s.sz * A[s.kz]), bz = double(s.sz * B[s.kz]), cz = double(s.sz * C[s.kz]);
  const double inv = 1.0 / det;
  const float t = float((U * az + V * bz + W * cz) * inv);
  if (!(t >= tnear && t <= tfar)) return false;  // also rejects NaN
  hit->t = t;
  hit->u = float(V * inv);
  hit->v = float(W * inv);
  return true;
}

}  // namespace tessera

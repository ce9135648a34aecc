// SPDX-License-Identifier: Apache-2.0
// Small analytic scenes (at most kScanSpheres spheres, no triangles): a whole packet's rays tested
// against every sphere in turn, directly, instead of through Embree's BVH and its callbacks.
//
// Why: on such a scene (the Whitted showcase: three spheres and a floor) a packet's traversal is
// mostly Embree's fixed cost: the packet's set-up, a box test per node and a callback that calls
// sphere_roots() for the spheres whose boxes the lanes reach. Here a float test (sphere_scan.h)
// tells, for all lanes and spheres at once, which lines pass near enough to a sphere to meet it,
// and sphere_roots() runs on those spheres only. The roots are the callbacks' roots, in the same
// double arithmetic, and a lane's hit is the nearest as Embree's would be: only an exact tie
// between two spheres (the same float t) may resolve differently (the lower sphere index here;
// traversal order there). Whole packets and partly filled ones are scanned alike, so in a
// scanned scene even such a tie does not depend on which samples share a packet.
#include <cmath>
#include <limits>

#include "render/ray_batch.h"
#include "render/render_scene_embree.h"
#include "render/sphere_roots.h"
#include "render/sphere_scan.h"

namespace tessera {

void RenderScene::scan_roots(const RayArrays& rays, const PrimRef* from, uint32_t lanes, size_t s, const float* tfar,
                             double* t) const {
  static_assert(kSphereLanes == kPacket);
  alignas(32) static constexpr float tnear[kPacket] = {};
  alignas(32) int32_t active[kPacket], leaving[kPacket];
  for (int i = 0; i < kPacket; ++i) {
    active[i] = int32_t((lanes >> i) & 1u);
    // (from[] holds only the packet's lanes: read for active ones alone)
    leaving[i] = active[i] && from[i].kind == PrimRef::Kind::kSphere && from[i].id == s ? 1 : 0;
  }
  const Sphere& sp = spheres_[s];
  sphere_roots({rays.ox, rays.oy, rays.oz, rays.dx, rays.dy, rays.dz, tnear, tfar, active, leaving}, sp.center,
               sp.radius, t);
}

void RenderScene::scan_intersect(const RayArrays& rays, const PrimRef* from, uint32_t lanes, float* tfar,
                                 uint32_t* geom, uint32_t* prim) const {
  uint32_t near[kScanSpheres];
  scan_candidates(rays, scan_table_, lanes, near);
  for (size_t s = 0; s < scan_.size(); ++s) {
    if (near[s] == 0) continue;
    double t[kPacket];
    scan_roots(rays, from, near[s], s, tfar, t);
    for (int i = 0; i < kPacket; ++i) {
      if (t[i] < 0) continue;
      // record_hit()'s fields, as the sphere callback writes them (the Ng it also writes is
      // not read for spheres).
      tfar[i] = float(t[i]);
      geom[i] = sphere_buckets_[scan_[s].bucket].geom_id;
      prim[i] = scan_[s].prim;
    }
  }
}

void RenderScene::scan_occluded(const RayArrays& rays, const PrimRef* from, const int* valid, float* tfar,
                                GlassHits* glass) const {
  uint32_t lanes = 0;
  for (int i = 0; i < kPacket; ++i) lanes |= valid[i] ? 1u << i : 0u;
  uint32_t near[kScanSpheres];
  scan_candidates(rays, scan_table_, lanes, near);
  uint32_t blocked = 0;
  for (size_t s = 0; s < scan_.size(); ++s) {
    const Sphere& sp = spheres_[s];
    if (scan_[s].bucket == 1) {
      // Glass: every crossing in (0, tfar) collected, as sphere_occluded() does.
      for (uint32_t m = near[s] & ~blocked; m != 0; m &= m - 1) {
        const int i = __builtin_ctz(m);
        add_glass_crossings(sp, uint32_t(s), from[i], Vec3d(rays.ox[i], rays.oy[i], rays.oz[i]),
                            Vec3d(rays.dx[i], rays.dy[i], rays.dz[i]), 0.0f, tfar[i], &glass[i]);
      }
      continue;
    }
    const uint32_t test = near[s] & ~blocked;
    if (test == 0) continue;
    double t[kPacket];
    scan_roots(rays, from, test, s, tfar, t);
    for (int i = 0; i < kPacket; ++i) blocked |= t[i] >= 0 ? 1u << i : 0u;
  }
  // Embree's mark of an occluded ray.
  for (uint32_t m = blocked; m != 0; m &= m - 1) tfar[__builtin_ctz(m)] = -std::numeric_limits<float>::infinity();
}

}  // namespace tessera

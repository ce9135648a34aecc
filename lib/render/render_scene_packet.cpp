// SPDX-License-Identifier: Apache-2.0
// Packet versions of RenderScene::intersect and ::transmittance: up to 8 rays in one Embree
// rtcIntersect8/rtcOccluded8 call (8 lanes = AVX2's width; Embree splits them for narrower
// ISAs). The camera rays of one pixel's consecutive samples, and the shadow rays from their hit
// points to one light, are coherent: one traversal serves them all. Around the Embree call, the
// planes and the sphere and plane hit points are computed for all lanes at once
// (render/ray_batch_simd.h, the scalar arithmetic lane for lane); triangle hits and glass
// products are the scalar code, per lane.
#include <algorithm>
#include <bit>
#include <cstring>

#include "render/plane.h"
#include "render/ray_batch.h"
#include "render/ray_batch_simd.h"
#include "render/ray_lanes.h"
#include "render/ray_log.h"
#include "render/render_scene_embree.h"

namespace tessera {

namespace {

template <typename R>
void set_lane(R* r, int lane, const Vec3f& o, const Vec3f& d, float tfar, uint32_t mask) {
  r->org_x[lane] = o.x;
  r->org_y[lane] = o.y;
  r->org_z[lane] = o.z;
  r->dir_x[lane] = d.x;
  r->dir_y[lane] = d.y;
  r->dir_z[lane] = d.z;
  r->tnear[lane] = 0.0f;
  r->tfar[lane] = tfar;
  r->time[lane] = 0.0f;
  r->mask[lane] = mask;
  r->id[lane] = uint32_t(lane);  // indexes TraceContext::from_by_id and ::glass
  r->flags[lane] = 0;
}

// set_lane() for all lanes of a packet, from arrays: whole arrays copied by fixed-size memcpy,
// which the compiler makes a few vector moves (a loop over the lanes stays scalar at -O2: the
// arrays might overlap, and the cheap vectorizer adds no run-time check).
template <typename R>
void set_lanes(R* r, const RayArrays& rb, const float* tfar, uint32_t mask) {
  constexpr size_t kBytes = sizeof(float) * kRayLanes;
  static_assert(sizeof(r->org_x) == kBytes);
  std::memcpy(r->org_x, rb.ox, kBytes);
  std::memcpy(r->org_y, rb.oy, kBytes);
  std::memcpy(r->org_z, rb.oz, kBytes);
  std::memcpy(r->dir_x, rb.dx, kBytes);
  std::memcpy(r->dir_y, rb.dy, kBytes);
  std::memcpy(r->dir_z, rb.dz, kBytes);
  std::memcpy(r->tfar, tfar, kBytes);
  for (int i = 0; i < kRayLanes; ++i) {
    r->tnear[i] = 0.0f;
    r->time[i] = 0.0f;
    r->mask[i] = mask;
    r->id[i] = uint32_t(i);
    r->flags[i] = 0;
  }
}

RTCRay lane_ray(const RTCRay8& r, int lane) {
  RTCRay x;
  x.org_x = r.org_x[lane];
  x.org_y = r.org_y[lane];
  x.org_z = r.org_z[lane];
  x.dir_x = r.dir_x[lane];
  x.dir_y = r.dir_y[lane];
  x.dir_z = r.dir_z[lane];
  x.tnear = r.tnear[lane];
  x.tfar = r.tfar[lane];
  x.time = 0.0f;
  x.mask = r.mask[lane];
  x.id = r.id[lane];
  x.flags = 0;
  return x;
}

}  // namespace

bool RenderScene::lanes_start_near(const RayArrays& r, int n) const {
  // starts_near() of lanes 0..n-1, in integers: |x| <= bound on floats is (bits(x) & 0x7FFFFFFF)
  // <= bits(bound) on their bit patterns as signed integers (non-negative floats order as their
  // bits; a NaN's exceed any finite bound's, so it is not near). The compiler makes these
  // compares vector instructions; the float loop it replaces stayed scalar (2.5 % of a Whitted
  // frame by perf).
  const int32_t bound = std::bit_cast<int32_t>(near_bound());
  int32_t far = 0;
  for (int i = 0; i < kPacket; ++i) {
    int32_t lane = 0;
    lane |= int32_t((std::bit_cast<int32_t>(r.ox[i]) & 0x7FFFFFFF) > bound);
    lane |= int32_t((std::bit_cast<int32_t>(r.oy[i]) & 0x7FFFFFFF) > bound);
    lane |= int32_t((std::bit_cast<int32_t>(r.oz[i]) & 0x7FFFFFFF) > bound);
    far |= lane & int32_t(i < n);
  }
  return far == 0;
}

void RenderScene::intersect_packet(const RayLanes& rays, const PrimRef* from, int n, Hit* hits, bool* found) const {
  static_assert(kRayLanes == kPacket);
  alignas(32) int valid[kPacket];
  alignas(32) RTCRayHit8 rh;
  // The planes for all lanes at once (render/ray_batch_simd.h: nearest_plane()'s arithmetic, lane
  // for lane), read from the packet's own arrays. Lanes past n are computed and ignored.
  const RayArrays rb = rays.arrays();
  alignas(64) int32_t plane[kPacket], left[kPacket];
  alignas(64) double tp[kPacket];
  alignas(64) float tfar[kPacket];
  double t0[kPacket];
  for (int i = 0; i < kPacket; ++i) left[i] = i < n && from[i].kind == PrimRef::Kind::kPlane ? int32_t(from[i].id) : -1;
  const PlaneTable planes{plane_table_.data(), plane_ids_.data(), planes_.size()};
  batch_nearest_planes(rb, size_t(n), planes, tp, plane, tfar, left);  // whole vectors up to lane n
  RayLog* const log = thread_ray_log();  // once a packet: a thread-local load per lane showed in perf
  for (int i = 0; i < kPacket; ++i) {
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  const bool near = lanes_start_near(rb, n) && !log;
  if (near) {
    // The common case, rays Embree takes as they are: the arrays copied whole, in loops of
    // fixed trip count the compiler turns into vector moves (the lane-by-lane loop below cost
    // 2 % of a Whitted frame); lanes past n are copied too, and left invalid. The sphere scan
    // reads the rays where they are and needs only tfar.
    if (scan_spheres_) {
      std::memcpy(rh.ray.tfar, tfar, sizeof rh.ray.tfar);
    } else {
      set_lanes(&rh.ray, rb, tfar, 0xFFFFFFFFu);
    }
    for (int i = 0; i < kPacket; ++i) {
      t0[i] = 0.0;
      valid[i] = i < n ? -1 : 0;
    }
  } else {
    for (int i = 0; i < kPacket; ++i) {
      valid[i] = 0;
      if (i >= n) continue;
      // embree_ray(), its common case written lane by lane: copying Ray structs here cost a
      // store-forwarding stall per lane (a fifth of this function's time, measured with perf).
      if (starts_near({rb.ox[i], rb.oy[i], rb.oz[i]})) {
        t0[i] = 0.0;
        set_lane(&rh.ray, i, {rb.ox[i], rb.oy[i], rb.oz[i]}, {rb.dx[i], rb.dy[i], rb.dz[i]}, tfar[i], 0xFFFFFFFFu);
      } else {
        const Ray ray{rays.o(i), rays.d(i), tfar[i]};
        Ray er = ray;  // embree_ray_from_far() moves the origin and shortens tmax of this copy
        t0[i] = embree_ray_from_far(ray, &er);
        set_lane(&rh.ray, i, er.o, er.d, er.tmax, 0xFFFFFFFFu);
      }
      if (log) {
        log->rays.push_back({lane_ray(rh.ray, i), from[i],
                             from[i].kind == PrimRef::Kind::kNone ? LoggedRay::Kind::kCamera : LoggedRay::Kind::kSecondary});
      }
      if (t0[i] >= 0.0) valid[i] = -1;  // else no bounded geometry within reach: planes only
    }
  }
  if (scan_spheres_ && near) {
    // Whole packets and partly filled ones alike, so that a sample's answer is the same in
    // either (exact ties between spheres are decided by sphere order, not traversal order).
    scan_intersect(rb, from, (1u << n) - 1u, rh.ray.tfar, rh.hit.geomID, rh.hit.primID);
  } else {
    TraceContext ctx;
    rtcInitIntersectContext(&ctx.rtc);
    ctx.scene = this;
    ctx.from_by_id = from;
    rtcIntersect8(valid, rtc_scene_.get(), &ctx.rtc, &rh);
  }
  // Sphere and plane hits are finished for all lanes at once (ray_batch_simd.h: finish_hit()'s
  // double arithmetic, lane for lane), triangles lane by lane (finish_hit()).
  constexpr uint32_t kPlaneLane = 1, kSphereLane = 2;
  alignas(64) uint32_t finish[kPacket] = {}, prim[kPacket] = {};
  uint32_t bucket[kPacket];
  static thread_local HitBatch simd;  // its 64 Hits are made once per thread, not per packet
  bool spheres = false, planes_hit = false;
  for (int i = 0; i < n; ++i) {
    const uint32_t g = rh.hit.geomID[i];
    const float t = t0[i] > 0.0 ? float(t0[i] + double(rh.ray.tfar[i])) : rh.ray.tfar[i];
    if (g == RTC_INVALID_GEOMETRY_ID) {
      found[i] = plane[i] >= 0;
      finish[i] = found[i] ? kPlaneLane : 0;
      planes_hit = planes_hit || found[i];
      continue;
    }
    const int k = g == sphere_buckets_[0].geom_id ? 0 : g == sphere_buckets_[1].geom_id ? 1 : -1;
    if (k >= 0 && spheres_.size() < (size_t(1) << 27)) {  // the SIMD finish reads 10 x index 32-bit words
      found[i] = true;
      finish[i] = kSphereLane;
      prim[i] = sphere_buckets_[k].ids[rh.hit.primID[i]];
      bucket[i] = uint32_t(k);
      simd.t[i] = t;
      spheres = true;
      continue;
    }
    found[i] = finish_hit(Vec3d(rays.o(i)), Vec3d(rays.d(i)), plane[i], tp[i], g, rh.hit.primID[i], rh.hit.u[i],
                          rh.hit.v[i], t, &hits[i]);
  }
  if (spheres) {
    const SphereTable table{&spheres_[0].center.x};
    batch_sphere_hits(rb, finish, kSphereLane, prim, size_t(n), table, &simd);
  }
  if (planes_hit) batch_plane_hits(rb, finish, kPlaneLane, tp, plane, size_t(n), planes, &simd);
  for (int i = 0; i < n; ++i) {
    if (finish[i] == 0) continue;
    Hit& h = hits[i];
    h.t = finish[i] == kSphereLane ? simd.t[i] : float(tp[i]);
    const Vec3f p{simd.px[i], simd.py[i], simd.pz[i]};
    h.n = {simd.nx[i], simd.ny[i], simd.nz[i]};
    h.smooth = false;
    if (finish[i] == kSphereLane) {
      finish_sphere_hit(prim[i], bucket[i], p, &h);
    } else {
      finish_plane_hit(plane[i], p, &h);
    }
  }
}

void RenderScene::intersect_packet(const Ray* rays, const PrimRef* from, int n, Hit* hits, bool* found) const {
  intersect_packet(RayLanes::of(rays, n), from, n, hits, found);
}

void RenderScene::transmittance_packet(const Ray* rays, const PrimRef* from, int n, Rgb* T) const {
  transmittance_packet(RayLanes::of(rays, n), from, n, T);
}

void RenderScene::transmittance_packet(const RayLanes& rays, const PrimRef* from, int n, Rgb* T) const {
  alignas(32) int valid[kPacket];
  alignas(32) RTCRay8 r;
  GlassHits glass[kPacket];
  const uint32_t mask = has_glass_ ? kOpaqueMask | kGlassMask : kOpaqueMask;
  bool open[kPacket] = {};  // not blocked by an opaque plane: Embree (if in reach) decides
  int live = 0;
  RayLog* const log = thread_ray_log();
  const RayArrays rb = rays.arrays();
  const bool near = lanes_start_near(rb, n) && !log;
  if (near && n == kPacket) {
    // The common case, a whole packet of rays Embree takes as they are (a full queue of shadow
    // rays): the opaque planes tested for all lanes at once (opaque_plane_blocks()'s arithmetic:
    // a blocking plane is the nearest plane in (0, tmax), batch_nearest_planes() on the opaque
    // planes' table), the arrays copied whole.
    alignas(64) int32_t blocker[kPacket], left[kPacket];
    // With one opaque plane (a ground) and every ray leaving it, there is nothing to test: a ray
    // never meets the plane it leaves (the shadow rays of a packet of ground hits).
    bool only_their_own = opaque_planes_.size() == 1;
    for (int i = 0; i < kPacket; ++i) {
      left[i] = from[i].kind == PrimRef::Kind::kPlane ? opaque_index_[from[i].id] : -1;
      only_their_own &= left[i] == 0;
    }
    if (!opaque_planes_.empty() && !only_their_own) {
      alignas(64) double tp[kPacket];
      alignas(64) float tfar[kPacket];
      const PlaneTable opaque{opaque_plane_table_.data(), opaque_plane_ids_.data(), opaque_planes_.size()};
      batch_nearest_planes(rb, size_t(kPacket), opaque, tp, blocker, tfar, left);
    } else {
      std::fill(blocker, blocker + kPacket, -1);
    }
    if (scan_spheres_) {
      std::memcpy(r.tfar, rb.tmax, sizeof r.tfar);  // all the scan reads of Embree's arrays
    } else {
      set_lanes(&r, rb, rb.tmax, mask);
    }
    for (int i = 0; i < kPacket; ++i) {
      open[i] = blocker[i] < 0;
      valid[i] = open[i] ? -1 : 0;
      if (!open[i]) T[i] = Rgb(0.0f);
      live += open[i] ? 1 : 0;
    }
  } else {
    for (int i = 0; i < kPacket; ++i) {
      valid[i] = 0;
      if (i >= n) continue;
      const Ray ray = rays.ray(i);
      if (opaque_plane_blocks(ray, from[i])) {
        T[i] = Rgb(0.0f);
        continue;
      }
      open[i] = true;
      double t0 = 0.0;  // embree_ray(), lane by lane as in intersect_packet
      if (starts_near(ray.o)) {
        set_lane(&r, i, ray.o, ray.d, ray.tmax, mask);
      } else {
        Ray er = ray;
        t0 = embree_ray_from_far(ray, &er);
        set_lane(&r, i, er.o, er.d, er.tmax, mask);
      }
      if (log) log->rays.push_back({lane_ray(r, i), from[i], LoggedRay::Kind::kShadow});
      if (t0 < 0.0) continue;  // no bounded geometry within reach: planes only (no glass hits)
      valid[i] = -1;
      ++live;
    }
  }
  if (live > 0 && near && scan_spheres_) {  // whole packets and partly filled ones, as in intersect_packet
    scan_occluded(rb, from, valid, r.tfar, glass);
  } else if (live > 0) {
    TraceContext ctx;
    rtcInitIntersectContext(&ctx.rtc);
    ctx.scene = this;
    ctx.from_by_id = from;
    if (has_glass_) ctx.glass = glass;
    rtcOccluded8(valid, rtc_scene_.get(), &ctx.rtc, &r);
  }
  for (int i = 0; i < n; ++i) {
    if (!open[i]) continue;
    if (valid[i] && r.tfar[i] < 0.0f) {
      T[i] = Rgb(0.0f);
    } else if (!has_glass_ || !may_cross_glass(glass[i])) {
      T[i] = Rgb(1.0f);  // glass_product's answer, without its set-up (most shadow rays)
    } else {
      TraceContext one;
      rtcInitIntersectContext(&one.rtc);
      one.scene = this;
      one.from = from[i];
      T[i] = glass_product(rays.ray(i), &one, &glass[i]);
    }
  }
}

}  // namespace tessera

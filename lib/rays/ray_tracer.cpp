// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_tracer.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include "rays/world_batch.h"
#include "render/ray_batch.h"
#include "render/shading_normal.h"

namespace tessera::rays {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The unit direction, in double. One that is unit length to within 2^-20 already is kept as
// given, so a float direction passes to the renderer bit for bit (its own camera rays are
// normalized floats: replaying one must give the renderer's exact hit).
[[gnu::always_inline]] inline Vec3d unit_direction(const Vec3d& d) {
  if (std::abs(length(d) - 1.0) <= kUnitTolerance) return d;
  const Vec3d s = d / max_component(abs(d));  // scaled first: |d| of 1e-300 or 1e300 is fine
  return s / length(s);
}

// [t_in, t_out] of the ray o + t d inside the cube |x| <= L (max norm), in double; false if it
// misses the cube.
bool cube_span(const Vec3d& o, const Vec3d& d, double L, double* t_in, double* t_out) {
  *t_in = -kInf;
  *t_out = kInf;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if (std::abs(o[k]) > L) return false;
      continue;
    }
    const double a = (-L - o[k]) / d[k], b = (L - o[k]) / d[k];
    *t_in = std::max(*t_in, std::min(a, b));
    *t_out = std::min(*t_out, std::max(a, b));
  }
  return *t_in <= *t_out;
}

}  // namespace

RayTracer::RayTracer(std::shared_ptr<const Scene> scene, std::shared_ptr<const RenderScene> frame)
    : scene_(std::move(scene)),
      frame_(std::move(frame)),
      origin_(render_origin(*frame_)),
      bounds_radius_(bounds_radius(*frame_)) {}

// Inlined: called once per ray by both queries (the call and the struct copy showed in callgrind).
[[gnu::always_inline]] inline RayTracer::Query RayTracer::query(const WorldRay& w) const {
  Query q;
  q.dd = unit_direction(w.d);
  const Vec3f d(q.dd);
  // Render space is world minus the eye, formed in double. A ray from the eye (a camera ray)
  // starts at exactly 0, as the renderer's do.
  const Vec3d o = w.o - origin_;
  // Where the float ray starts, as a distance along the ray: t_min (the query asks nothing
  // before it), or further for a far origin. The renderer itself only traces rays from the
  // eye or from surfaces; a client may start one a million units away, where float spacing
  // would bend it past a small mesh. So a far ray (beyond 16x the radius R of all bounded
  // geometry, the renderer's own "far" threshold) moves, in double, to where it enters the
  // cube |x| <= 2R that holds that geometry; the stretch before it can only cross infinite
  // planes, and gets its own query (`before`) from the unmoved start.
  q.shift = double(w.tmin);
  // Distances are floats: a plane met 1e52 away (a near-parallel ray from far off) is beyond
  // what t can say, so it counts as no hit rather than a hit at t = infinity.
  const double tmax = std::min(double(w.tmax), double(std::numeric_limits<float>::max()));
  const double R = double(bounds_radius_);
  const Vec3d start = o + q.dd * q.shift;
  double t_in = 0.0, t_out = 0.0;
  if (R > 0.0 && max_component(abs(start)) > far_limit() && cube_span(start, q.dd, 2.0 * R, &t_in, &t_out) &&
      t_out > 0.0 && t_in > 0.0 && t_in < tmax - q.shift) {
    q.before = {Vec3f(start), d, float(t_in)};
    q.has_before = true;
    q.after_shift = q.shift + t_in;
    q.after = {Vec3f(o + q.dd * q.after_shift), d, float(tmax - q.after_shift)};
  } else {
    q.after_shift = q.shift;  // the common case: the ray starts where it asks
    q.after = {Vec3f(start), d, float(tmax - q.shift)};
  }
  return q;
}

bool RayTracer::trace(const WorldRay& w, WorldHit* out) const {
  const RenderScene& rs = *frame_;
  const Query q = query(w);
  Hit h;
  if (q.has_before && intersect(rs, q.before, PrimRef{}, &h)) return to_world(h, q.shift, Vec3f(q.dd), out);
  return intersect(rs, q.after, PrimRef{}, &h) && to_world(h, q.after_shift, Vec3f(q.dd), out);
}

bool RayTracer::to_world(const Hit& h, double shift, const Vec3f& d, WorldHit* out) const {
  const RenderScene& rs = *frame_;
  // The same for a surface point beyond float range (render space is float): no hit to report.
  if (!std::isfinite(h.t) || !is_finite(h.p)) return false;
  // t: exact when nothing moved (shift 0), else the moved start's distance added in double.
  out->t = shift == 0.0 ? h.t : float(shift + double(h.t));
  out->p = origin_ + Vec3d(h.p);
  out->n = h.n;
  // The integrator shades with the normal turned towards the side the ray came from
  // (integrator.cpp: front = dot(d, n) < 0): the geometric one, or a mesh's interpolated one.
  // The sign bits flipped where it faces away: exactly h.n * -1 (the normal is finite), without
  // the branch a select compiled to, mispredicted on every other incoherent ray.
  const uint32_t flip = uint32_t(!(dot(d, h.n) < 0.0f)) << 31;
  auto turned = [flip](float x) { return std::bit_cast<float>(std::bit_cast<uint32_t>(x) ^ flip); };
  const float fx = turned(h.n.x), fy = turned(h.n.y), fz = turned(h.n.z);
  if (h.smooth) {
    out->ns = facing(h.ns, h.n, Vec3f(fx, fy, fz));
  } else {
    // Component by component: a Vec3f temporary went through the stack, and the 8-byte load
    // that copied it stalled on store forwarding (60 % of this function, perf annotate).
    out->ns.x = fx;
    out->ns.y = fy;
    out->ns.z = fz;
  }
  out->u = h.u;
  out->v = h.v;
  const PrimSource src = source_of(rs, h.prim);
  out->object = src.object;
  out->primitive = src.primitive;
  out->material = h.material;
  return true;
}

bool RayTracer::blocked(const WorldRay& w) const {
  const RenderScene& rs = *frame_;
  const Query q = query(w);
  // any_hit() turns down a plane point beyond float range, as trace() does below. (A point on
  // `before` never is: it lies between the start and the geometry's cube.)
  return (q.has_before && any_hit(rs, q.before, PrimRef{})) || any_hit(rs, q.after, PrimRef{});
}

template <class Emit>
void RayTracer::nearest_each(const WorldRay* rays, size_t n, Emit& emit) const {
  // Rays go to intersect_batch() kRayBatch at a time, as arrays of components, so
  // that the arithmetic around each Embree query runs in SIMD across rays (world_batch.h,
  // render/ray_batch.h); each answer is still intersect()'s for that ray alone, bit for bit. A
  // far ray, which needs two queries, goes alone (trace()).
  auto alone = [&](size_t i) {
    WorldHit h;
    h.hit = trace(rays[i], &h);
    emit.scalar(i, h.hit ? h : WorldHit{});  // trace() writes every field of a hit, none of a miss
  };
  if (n < 4) {  // a few rays: the batch's set-up would cost more than the vectors save
    for (size_t i = 0; i < n; ++i) alone(i);
    return;
  }
  const RenderScene& rs = *frame_;
  const Vec3d origin = origin_;
  const double far = far_limit();
  RayBatch batch;
  HitBatch found;
  WorldAnswers answers;
  alignas(64) double shift[kRayBatch];
  for (size_t base = 0; base < n; base += kRayBatch) {
    const size_t m = std::min(kRayBatch, n - base);
    world_to_render(rays + base, m, origin, far, &batch, shift);
    intersect_batch(rs, batch, m, &found);
    tessera::rays::to_world(found, batch, shift, m, origin, &answers);
    emit.batch(base, answers, m);  // every lane (a miss's defaults included); the scalar code's below
    const size_t ahead = std::min(n - base - m, kRayBatch);  // the next batch's rays
    for (size_t j = 0; j < m; ++j) {
      // Asked for now, they arrive while this batch is answered (without it, the first touch of
      // each ray was a tenth of the whole query; a loop of prefetches alone stalled, perf).
      if (j < ahead) __builtin_prefetch(&rays[base + m + j]);
      if (batch.skip[j]) {
        alone(base + j);  // far: query() decides, trace() answers
      } else if (found.status[j] == HitBatch::kHit) {
        // The scalar code's hit (a mesh with vertex normals, a ray from far away).
        WorldHit h;
        h.hit = to_world(found.hit[j], shift[j], Vec3f(batch.dx[j], batch.dy[j], batch.dz[j]), &h);
        emit.scalar(base + j, h.hit ? h : WorldHit{});
      }
    }
  }
}

void RayTracer::nearest(const WorldRay* rays, size_t n, WorldHit* hits) const {
  struct {
    WorldHit* hits;
    void scalar(size_t i, const WorldHit& h) { hits[i] = h; }
    void batch(size_t base, const WorldAnswers& a, size_t m) {
      for (size_t j = 0; j < m; ++j) {
        WorldHit& out = hits[base + j];
        out.hit = a.hit[j] != 0;
        out.t = a.t[j];
        out.p = {a.px[j], a.py[j], a.pz[j]};
        out.n = {a.nx[j], a.ny[j], a.nz[j]};
        out.ns = {a.nsx[j], a.nsy[j], a.nsz[j]};
        out.u = a.u[j];
        out.v = a.v[j];
        out.object = a.object[j];
        out.primitive = a.primitive[j];
        out.material = a.material[j];
      }
    }
  } emit{hits};
  nearest_each(rays, n, emit);
}

void RayTracer::nearest_into(const WorldRay* rays, size_t n, const HitColumns& out, size_t offset) const {
  // Each asked array written straight from the batch's arrays, a vector at a time.
  struct {
    const HitColumns& c;
    size_t offset;
    void scalar(size_t i, const WorldHit& h) { write_hit(c, offset + i, h); }
    void batch(size_t base, const WorldAnswers& a, size_t m) { store_hit_columns(a, m, c, offset + base); }
  } emit{out, offset};
  nearest_each(rays, n, emit);
}

void RayTracer::occluded(const WorldRay* rays, size_t n, WorldHit* hits) const {
  // As nearest(): batches of rays as arrays, a far ray alone (blocked() moves its start).
  if (n < 4) {
    for (size_t i = 0; i < n; ++i) {
      hits[i] = WorldHit{};
      hits[i].hit = blocked(rays[i]);
    }
    return;
  }
  const RenderScene& rs = *frame_;
  RayBatch batch;
  alignas(64) double shift[kRayBatch];
  uint8_t flag[kRayBatch];
  for (size_t base = 0; base < n; base += kRayBatch) {
    const size_t m = std::min(kRayBatch, n - base);
    world_to_render(rays + base, m, origin_, far_limit(), &batch, shift);
    any_hit_batch(rs, batch, m, flag);
    for (size_t j = 0; j < m; ++j) {
      hits[base + j] = WorldHit{};
      hits[base + j].hit = batch.skip[j] ? blocked(rays[base + j]) : flag[j] != 0;
    }
  }
}

}  // namespace tessera::rays

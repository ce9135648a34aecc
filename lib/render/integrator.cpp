// SPDX-License-Identifier: Apache-2.0
#include "render/integrator.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "render/fresnel.h"
#include "render/isa_clones.h"
#include "render/ray_lanes.h"
#include "render/secondary_rays.h"
#include "render/shadow_rays.h"
#include "render/shading_normal.h"

namespace tessera {

namespace {

constexpr float kInvPi = float(1.0 / std::numbers::pi);
constexpr float kShadowEpsilon = 1e-4f;  // relative shortening of rays aimed at a surface point

// Russian roulette on the path tree (ImageSettings::roulette_weight, t). A child ray's weight is
// the largest channel of the product of the mirror reflectances, Fresnel factors and glass
// transmittances between it and the camera. A child whose weight w is below t is traced with
// probability w / t and, when traced, counts t / w times: the pixel's expected value is unchanged
// (no bias, unlike a hard cut-off such as POV-Ray's adc_bailout), and the error estimate sees the
// variance it adds. Why: a glass sphere's tree doubles at every surface, and most of its rays are
// internal reflections weighted 0.04^k; on the Whitted showcase at 16 spp, t = 0.01 keeps 2.2 M of
// 5.3 M secondary rays for an RMSE 0.05% higher (docs/performance.md, "Russian roulette"). The
// draw uses the parent node's own sampler dimension, so a lane's result still depends only on its
// own sample; with t = 0 no weight is below it and every branch is traced, bit for bit as without
// the roulette.
constexpr uint64_t kRouletteDim = 2000003u;  // hash_combine(node, this): apart from the area lights' 1000003 + li

struct Context {
  const RenderScene& scene;
  const PixelSampler& sampler;
  RayCounts* counts;
};

// One shadow ray of direct lighting: the light's contribution is transmittance * a * b.
struct ShadowQuery {
  Ray ray;
  Rgb a;
  float b;
};

// The shadow query of area light `li` (one sample, drawn from the pixel sample's stream at `node`)
// from a diffuse point, if the light is above it: f(query). Lane by lane: it draws from each
// lane's own sampler.
template <typename F>
void area_light_query(const Context& c, const Hit& hit, const Vec3f& n_f, uint64_t node, size_t li, F&& f) {
  const Vec3f ns_f = hit.smooth ? facing(hit.ns, hit.n, n_f) : n_f;
  auto cosine = [&](const Vec3f& w) { return hit.smooth ? smooth_light_cosine(n_f, ns_f, w) : dot(n_f, w); };
  const auto& L = c.scene.area_lights()[li];
  float u = 0.0f, v = 0.0f;  // get_2d() sets both (zeros only quiet a warning once it is inlined)
  c.sampler.get_2d(hash_combine(node, 1000003u + li), &u, &v);
  // Choose a triangle by area, then reuse u's remainder inside it (stays stratified).
  const size_t k = std::min(size_t(std::upper_bound(L.cdf.begin(), L.cdf.end(), u) - L.cdf.begin()), L.cdf.size() - 1);
  const float lo = k == 0 ? 0.0f : L.cdf[k - 1];
  const float span = L.cdf[k] - lo;
  u = span > 0 ? std::clamp((u - lo) / span, 0.0f, 1.0f) : 0.5f;
  // Uniform point on the triangle (the square-root parametrization, pbrt's SampleUniformTriangle).
  const float su = std::sqrt(u);
  const float b0 = 1.0f - su, b1 = v * su, b2 = 1.0f - b0 - b1;
  const Vec3f a = L.v[3 * k], b = L.v[3 * k + 1], cc = L.v[3 * k + 2];
  const Vec3f q = a * b0 + b * b1 + cc * b2;
  const Vec3f q_err = (abs(a * b0) + abs(b * b1) + abs(cc * b2)) * gamma_bound(7);
  const Vec3f nl = normalize(cross(b - a, cc - a));
  Vec3f to = q - hit.p;
  const float r2 = dot(to, to);
  if (!(r2 > 0.0f)) return;
  const Vec3f w = to / std::sqrt(r2);
  const float cos_t = cosine(w);
  const float cos_l = -dot(nl, w);  // emitters emit from their front (CCW) face only
  if (!(cos_t > 0.0f) || !(cos_l > 0.0f)) return;
  const Vec3f o = offset_ray_origin(hit.p, hit.p_err, n_f, w);
  const Vec3f target = offset_ray_origin(q, q_err, nl, -w);
  const Vec3f seg = target - o;
  const float dist = length(seg);
  if (!(dist > 0.0f)) return;
  // Irradiance estimate: Le cos_t cos_l / r^2 divided by the pdf 1/area.
  f(ShadowQuery{{o, seg / dist, dist * (1.0f - kShadowEpsilon)}, L.emission, cos_t * cos_l / r2 * L.area});
}

// What a hit sends on: whether it sends a reflection (path node 2k) and a refraction (2k + 1)
// ray, and the Fresnel weight between them.
struct Secondary {
  bool reflect = false, refract = false;
  float R = 0;  // glass: Fresnel reflectance
};

// Sets w[k] to the weights of the children that `sec` sends from a hit of material `m` reached
// with weight `weight`, plays the roulette on those below t (clearing the ones it drops from
// *sec) and sets scale[k] for the ones it keeps.
void roulette(const Material& m, float weight, float t, const PixelSampler& sampler, uint64_t node, Secondary* sec,
              float w[2], float scale[2]) {
  const auto max3 = [](const Rgb& c) { return std::max({c.x, c.y, c.z}); };
  if (m.type == Material::Type::kMirror) {
    w[0] = weight * max3(m.reflectance);
  } else {
    w[0] = weight * sec->R;
    w[1] = weight * (1.0f - sec->R) * max3(m.transmittance);
  }
  bool* sent[2] = {&sec->reflect, &sec->refract};
  if (!((*sent[0] && w[0] < t) || (*sent[1] && w[1] < t))) return;
  float u[2];
  sampler.get_2d(hash_combine(node, kRouletteDim), &u[0], &u[1]);
  for (int k = 0; k < 2; ++k) {
    if (!*sent[k] || !(w[k] < t)) continue;
    // A weight under t * 2^-24 (the smallest step of u) would survive only on u == 0, with a
    // scale that can overflow to infinity: such a branch is dropped, a bias of at most that weight
    // times its radiance (6e-10 of it at t = 0.01).
    if (w[k] >= t * 0x1p-24f && u[k] * t < w[k]) {
      scale[k] = t / w[k];
      w[k] = t;
    } else {
      *sent[k] = false;
    }
  }
}

// Sets *sec for a hit reached along direction `d`, and writes the rays it sends into lane
// `lane[0]` of *reflected and `lane[1]` of *refracted (left as they are when not sent): straight
// into the children's packets.
void plan_secondary(const Context& c, const Vec3f& d, const Hit& hit, int depth, Secondary* sec, RayLanes* reflected,
                    RayLanes* refracted, const int lane[2]) {
  Secondary& out = *sec;
  out.reflect = out.refract = false;
  const Material& m = c.scene.material(hit.material);
  if (m.type == Material::Type::kDiffuse || depth >= c.scene.image().max_depth) return;
  // The normal says which side is outside; shading happens on the side the ray came from.
  const bool front = dot(d, hit.n) < 0.0f;
  const Vec3f n_facing = front ? hit.n : -hit.n;
  // Mirrors and glass turn rays about this normal, kept on their side of the facet (shading_normal.h).
  const Vec3f n_turn = hit.smooth ? turning_normal(n_facing, facing(hit.ns, hit.n, n_facing), d) : n_facing;
  if (m.type == Material::Type::kMirror) {
    Vec3f w = normalize(reflect(d, n_turn));
    if (hit.smooth) w = keep_side(w, n_facing, true, normalize(reflect(d, n_facing)));
    out.reflect = true;
    reflected->set(lane[0], offset_ray_origin(hit.p, hit.p_err, n_facing, w), w);
    return;
  }
  // Glass. Outside is vacuum/air (index 1).
  const float eta_i = front ? 1.0f : float(m.ior), eta_t = front ? float(m.ior) : 1.0f;
  const float cos_i = -dot(d, n_turn);
  float cos_t = 0.0f;
  out.R = fresnel_dielectric(cos_i, eta_i, eta_t, &cos_t);
  if (out.R > 0.0f) {
    Vec3f w = normalize(reflect(d, n_turn));
    if (hit.smooth) w = keep_side(w, n_facing, true, normalize(reflect(d, n_facing)));
    out.reflect = true;
    reflected->set(lane[0], offset_ray_origin(hit.p, hit.p_err, n_facing, w), w);
  }
  if (out.R < 1.0f) {
    Vec3f w = refract(d, n_turn, eta_i / eta_t, cos_i, cos_t);
    if (hit.smooth) w = keep_side(w, n_facing, false, d);
    out.refract = true;
    refracted->set(lane[1], offset_ray_origin(hit.p, hit.p_err, n_facing, w), w);
  }
}

// Radiance leaving `hit` back along the arriving direction `d`, from the hit's direct lighting
// (diffuse; before albedo/pi) and the radiance its secondary rays brought back (mirror, glass).
Rgb shade(const Context& c, const Vec3f& d, const Hit& hit, const Rgb& direct, const Secondary& sec,
          const Rgb& reflected, const Rgb& refracted) {
  const RenderScene& s = c.scene;
  const Material& m = s.material(hit.material);
  // Emitters are seen from their front only.
  const bool front = dot(d, hit.n) < 0.0f;
  Rgb L = front ? m.emission : Rgb(0.0f);
  switch (m.type) {
    case Material::Type::kDiffuse: {
      const Rgb albedo = m.albedo_texture >= 0 ? s.textured_albedo(hit, m)
                         : m.checker && s.checker_parity(hit, m) ? m.albedo2 : m.albedo;
      L += albedo * direct * kInvPi;
      break;
    }
    case Material::Type::kMirror:
      if (sec.reflect) L += m.reflectance * reflected;
      break;
    case Material::Type::kGlass:
      if (sec.reflect) L += reflected * sec.R;
      if (sec.refract) L += m.transmittance * refracted * (1.0f - sec.R);
      break;
  }
  return L;
}

// The packet's flat mirror and glass hits, for their children's set-up across lanes
// (render/secondary_rays.h); whether there are any. Other lanes, and a lone flat lane (it costs
// less through plan_secondary, the same arithmetic, so the same bits), are left to
// plan_secondary.
bool turning_points(const RenderScene& scene, const RayLanes& rays, const Hit* hits, const int8_t* turns, int depth,
                    TurningPoints* out) {
  constexpr int P = RenderScene::kPacket;
  TurningPoints& tp = *out;
  int flats = 0;
  for (int i = 0; i < P; ++i) {
    const bool flat = turns[i] != 0 && !hits[i].smooth;  // turns: 0 at the last depth
    tp.live[i] = flat ? 1 : 0;
    flats += flat ? 1 : 0;
  }
  if (flats < 2) {
    std::fill(tp.live, tp.live + P, 0);
    return false;
  }
  for (int i = 0; i < P; ++i) {
    const Hit& h = hits[i];
    const bool flat = tp.live[i] != 0;
    const Material* mat = flat ? &scene.material(h.material) : nullptr;
    // Other lanes hold zeros: computed on, never used.
    const Vec3f ray_d = rays.d(i);
    const bool front = flat && dot(ray_d, h.n) < 0.0f;
    const Vec3f nf = !flat ? Vec3f(0.0f) : front ? h.n : -h.n;
    const Vec3f p = flat ? h.p : Vec3f(0.0f), e = flat ? h.p_err : Vec3f(0.0f), d = flat ? ray_d : Vec3f(0.0f);
    tp.at.set(i, p, e, nf);
    tp.dx[i] = d.x, tp.dy[i] = d.y, tp.dz[i] = d.z;
    const bool glass = flat && mat->type == Material::Type::kGlass;
    tp.glass[i] = glass ? 1 : 0;
    // Outside is vacuum/air (index 1).
    tp.eta_i[i] = !glass ? 1.0f : front ? 1.0f : float(mat->ior);
    tp.eta_t[i] = !glass ? 1.0f : front ? float(mat->ior) : 1.0f;
  }
  return true;
}

// The packet's diffuse hits as shading points (render/shadow_rays.h), for their shadow rays'
// set-up across lanes; whether there are any. Each lane's material kind is looked up once, here:
// turns[i] is 1 for a mirror or glass hit below the last depth (it sends children).
bool shading_points(const RenderScene& scene, const RayLanes& rays, const Hit* hits, const bool* found, int n, int depth,
                    ShadingPoints* out, int8_t* turns) {
  constexpr int P = RenderScene::kPacket;
  ShadingPoints& sp = *out;
  bool any = false;
  const bool deeper = depth < scene.image().max_depth;
  for (int i = 0; i < P; ++i) {
    const bool hit = i < n && found[i];
    const Material::Type type = hit ? scene.material(hits[i].material).type : Material::Type::kDiffuse;
    const bool diffuse = hit && type == Material::Type::kDiffuse;
    turns[i] = hit && deeper && type != Material::Type::kDiffuse ? 1 : 0;
    const Hit& h = hits[i];
    // Lanes without a diffuse hit hold zeros: computed on, never traced.
    const Vec3f n_f = !diffuse ? Vec3f(0.0f) : dot(rays.d(i), h.n) < 0.0f ? h.n : -h.n;
    const Vec3f ns_f = diffuse && h.smooth ? facing(h.ns, h.n, n_f) : n_f;
    const Vec3f p = diffuse ? h.p : Vec3f(0.0f), e = diffuse ? h.p_err : Vec3f(0.0f);
    sp.at.set(i, p, e, n_f);
    sp.sx[i] = ns_f.x, sp.sy[i] = ns_f.y, sp.sz[i] = ns_f.z;
    sp.g_dot_s[i] = dot(n_f, ns_f);  // smooth_light_cosine's dot(ng_facing, ns_facing)
    sp.smooth[i] = diffuse && h.smooth ? 1 : 0;
    sp.live[i] = diffuse ? 1 : 0;
    any = any || diffuse;
  }
  return any;
}

// The integrator: n <= P rays of one pixel's samples at the same path node (`node`: 1 for camera
// rays, 2k / 2k + 1 for the reflection / refraction children of node k), traced as one packet.
// Their shadow rays go in packets, light after light, and their children in one packet per
// child node, so a pixel's samples stay together down the tree. A lane's result depends only on
// its own ray and sampler, never on the other lanes (integrator_test.cpp): a single ray is a
// packet of one, the same code.
//
// Its arrays live in one frame per depth, made once per thread: a packet's hits, rays and
// results are over 3 KB, and zero-filling them on every call (their members have default
// initializers) cost more than the packet's Embree traversal (measured on the Whitted scene).
struct PacketFrame {
  static constexpr int P = RenderScene::kPacket;
  static_assert(P == kShadowLanes && P == kTurnLanes && P == kRayLanes);
  Hit hits[P];
  bool found[P];
  Rgb direct[P];
  Secondary sec[P];
  Rgb child_L[2][P];
  Rgb child_out[P];  // a child packet's results, by its own lanes
  // The reflection [0] and refraction [1] packets: rays, origin primitives, samplers, lanes.
  RayLanes child_r[2];
  PrimRef child_f[2][P];
  const PixelSampler* child_smp[2][P];
  int child_lane[2][P];
  float child_w[2][P];
  float child_scale[2][P];
  RayLanes r;  // a shadow packet's rays and their origin primitives
  PrimRef f[P];
  Rgb T[P];
  Rgb qa[P];  // the queued shadow rays' weights a and b (ShadowQuery's), by packet lane
  float qb[P];
  ShadingPoints points;  // the diffuse hits, for the shadow rays' set-up
  ShadowRays shadow;
  TurningPoints turning;  // the flat mirror and glass hits, for their children's set-up
  SecondaryRays turned;
  int lane_of[P];
  int8_t turns[P];  // 1: a mirror or glass hit below the last depth (it sends children)
};

std::vector<PacketFrame>& packet_frames() {
  static thread_local std::vector<PacketFrame> frames;
  return frames;
}

// Compiled for AVX2 and the baseline (render/isa_clones.h): its lane loops, and the shading and
// checker it inlines, are plain C++. Flattened: every helper of this file it calls (shade(),
// shading_points(), the light queue's lambdas, ...) is inlined into each version. Without it GCC
// kept them as out-of-line baseline functions once radiance_packet had two versions, and the
// AVX2 one gained a third of what it does with them (1438 against 1349 instructions a sample on
// the Whitted showcase; 1450 before).
TESSERA_ISA_CLONES_FLAT void radiance_packet(const RenderScene& scene, const RayLanes& rays, const PrimRef* from,
                                             const PixelSampler* const* samplers, const float* weight, int n,
                                             int depth, uint64_t node, RayCounts* counts, Rgb* out) {
  constexpr int P = RenderScene::kPacket;
  PacketFrame& fr = packet_frames()[size_t(depth)];  // sized by trace_radiance_packet
  Hit* hits = fr.hits;
  bool* found = fr.found;
  scene.intersect_packet(rays, from, n, hits, found);

  // Direct light at the diffuse hits, light by light (point, spot, directional, area): the rays
  // to one light from the samples of one pixel are coherent. Point, spot and directional rays
  // are set up for all lanes at once (render/shadow_rays.h); an area light's, which draw from
  // each lane's sampler, lane by lane (area_light_query). Each lane sums its lights in that
  // order.
  Rgb* direct = fr.direct;
  for (int i = 0; i < P; ++i) direct[i] = Rgb(0.0f);
  ShadingPoints& sp = fr.points;
  int8_t* turns = fr.turns;
  const bool any = shading_points(scene, rays, hits, found, n, depth, &sp, turns);
  // The queue of shadow rays, light after light: traced whenever it holds a full packet (with
  // fewer samples a pixel than a packet's lanes, the rays to several lights share one), and each
  // lane adds its light, transmittance x a x b, in the order its queries were queued.
  // trace() sends `count` shadow rays as one packet, ray j leaving lane lane(j) with weights
  // a(j) and b(j): from the queue, or straight from a light's set-up (queue_lanes).
  auto trace = [&](const RayLanes& r, int count, auto lane, auto a, auto b) {
    counts->shadow += uint64_t(count);
    for (int j = 0; j < count; ++j) fr.f[j] = hits[lane(j)].prim;
    scene.transmittance_packet(r, fr.f, count, fr.T);
    for (int j = 0; j < count; ++j) direct[lane(j)] += fr.T[j] * a(j) * b(j);
  };
  int queued = 0;
  auto flush = [&] {
    if (queued == 0) return;
    trace(fr.r, queued, [&](int j) { return fr.lane_of[j]; }, [&](int j) { return fr.qa[j]; },
          [&](int j) { return fr.qb[j]; });
    queued = 0;
  };
  auto queue = [&](int lane, const Ray& ray, const Rgb& a, float b) {
    fr.r.set(queued, ray);
    fr.qa[queued] = a;
    fr.qb[queued] = b;
    fr.lane_of[queued++] = lane;
    if (queued == P) flush();
  };
  // One light's rays set up for all lanes at once (render/shadow_rays.h), queued lane by lane;
  // or, when they are a whole packet by themselves (an empty queue, every lane lit: the common
  // case at 8 or more samples a pixel), traced from where they were set up. That is the packet
  // the queue would make, in its order, with the same products: the same bits, without the
  // copies.
  auto queue_lanes = [&](const ShadowRays& sr, const Rgb& intensity, bool spot) {
    const auto a = [&](int i) { return spot ? intensity * sr.cone[i] : intensity; };
    const auto b = [&](int i) { return sr.b[i]; };
    int32_t lit = 1;
    for (int i = 0; i < P; ++i) lit &= sr.live[i];  // live: 0 or 1
    if (queued == 0 && n == P && lit != 0) {
      trace(sr.rays, P, [](int j) { return j; }, a, b);
      return;
    }
    for (int i = 0; i < n; ++i) {
      if (sr.live[i]) queue(i, sr.rays.ray(i), a(i), b(i));
    }
  };
  if (any) {
    ShadowRays& sr = fr.shadow;
    for (const auto& l : scene.point_lights()) {
      point_light_rays(sp, l.position, nullptr, &sr);
      queue_lanes(sr, l.intensity, false);
    }
    for (const auto& l : scene.spot_lights()) {
      const SpotCone cone{l.direction, l.cone_scale, l.cone_offset};
      point_light_rays(sp, l.position, &cone, &sr);
      queue_lanes(sr, l.intensity, true);
    }
    for (const auto& l : scene.directional_lights()) {
      directional_light_rays(sp, -l.direction, &sr);
      queue_lanes(sr, l.irradiance, false);
    }
    for (size_t li = 0; li < scene.area_lights().size(); ++li) {
      for (int i = 0; i < n; ++i) {
        if (!sp.live[i]) continue;
        const Context c{scene, *samplers[i], counts};
        area_light_query(c, hits[i], sp.at.n(i), node, li,
                         [&](const ShadowQuery& q) { queue(i, q.ray, q.a, q.b); });
      }
    }
    flush();
  }

  // Children: one packet of the lanes' reflection rays, one of their refraction rays. The rays of
  // flat mirror and glass hits are set up for all lanes at once (render/secondary_rays.h, the
  // arithmetic of plan_secondary); a smooth hit's by plan_secondary, which writes them straight
  // into their packets.
  const TurningPoints& tp = fr.turning;
  const SecondaryRays& tr = fr.turned;
  if (turning_points(scene, rays, hits, turns, depth, &fr.turning)) secondary_rays(tp, &fr.turned);
  Secondary* sec = fr.sec;
  const float roulette_t = float(scene.image().roulette_weight);
  int m[2] = {0, 0};
  for (int i = 0; i < n; ++i) {
    if (!found[i]) continue;
    if (tp.live[i]) {
      sec[i].reflect = tr.reflect[i] != 0;
      sec[i].refract = tr.refract[i] != 0;
      sec[i].R = tr.R[i];  // glass only (shade reads it for glass)
      if (sec[i].reflect) fr.child_r[0].set(m[0], {tr.rox[i], tr.roy[i], tr.roz[i]}, {tr.rdx[i], tr.rdy[i], tr.rdz[i]});
      if (sec[i].refract) fr.child_r[1].set(m[1], {tr.tox[i], tr.toy[i], tr.toz[i]}, {tr.tdx[i], tr.tdy[i], tr.tdz[i]});
    } else if (turns[i]) {
      plan_secondary({scene, *samplers[i], counts}, rays.d(i), hits[i], depth, &sec[i], &fr.child_r[0], &fr.child_r[1],
                     m);
    } else {
      sec[i].reflect = sec[i].refract = false;  // plan_secondary's answer for a diffuse hit or the last depth
    }
    if (!sec[i].reflect && !sec[i].refract) continue;
    float w[2] = {0.0f, 0.0f}, scale[2] = {1.0f, 1.0f};
    roulette(scene.material(hits[i].material), weight[i], roulette_t, *samplers[i], node, &sec[i], w, scale);
    for (int k = 0; k < 2; ++k) {
      if (!(k == 0 ? sec[i].reflect : sec[i].refract)) continue;
      fr.child_w[k][m[k]] = w[k];
      fr.child_scale[k][m[k]] = scale[k];
      fr.child_f[k][m[k]] = hits[i].prim;
      fr.child_smp[k][m[k]] = samplers[i];
      fr.child_lane[k][m[k]++] = i;
    }
  }
  for (int k = 0; k < 2; ++k) {
    if (m[k] == 0) continue;
    counts->secondary += uint64_t(m[k]);
    radiance_packet(scene, fr.child_r[k], fr.child_f[k], fr.child_smp[k], fr.child_w[k], m[k], depth + 1,
                    2 * node + uint64_t(k), counts, fr.child_out);
    for (int j = 0; j < m[k]; ++j) {
      const float sc = fr.child_scale[k][j];
      fr.child_L[k][fr.child_lane[k][j]] = sc == 1.0f ? fr.child_out[j] : fr.child_out[j] * sc;
    }
  }

  for (int i = 0; i < n; ++i) {
    if (!found[i]) {
      out[i] = scene.background();
      continue;
    }
    const Context c{scene, *samplers[i], counts};
    out[i] = shade(c, rays.d(i), hits[i], direct[i], sec[i], fr.child_L[0][i], fr.child_L[1][i]);
  }
}

}  // namespace

Rgb trace_radiance(const RenderScene& scene, const Ray& ray, const PixelSampler& sampler, RayCounts* counts) {
  Rgb out;
  trace_radiance_packet(scene, &ray, &sampler, 1, counts, &out);
  return out;
}

void trace_radiance_packet(const RenderScene& scene, const Ray* rays, const PixelSampler* samplers, int n,
                           RayCounts* counts, Rgb* out) {
  trace_radiance_packet(scene, RayLanes::of(rays, n), samplers, n, counts, out);
}

void trace_radiance_packet(const RenderScene& scene, const RayLanes& rays, const PixelSampler* samplers, int n,
                           RayCounts* counts, Rgb* out) {
  constexpr int P = RenderScene::kPacket;
  const PrimRef none[P] = {};
  const PixelSampler* smp[P];
  for (int i = 0; i < n; ++i) smp[i] = &samplers[i];
  auto& frames = packet_frames();
  // One frame per depth 0..max_depth, made before the recursion holds references into them.
  if (frames.size() < size_t(scene.image().max_depth) + 1) frames.resize(size_t(scene.image().max_depth) + 1);
  float camera[P];  // a camera ray's weight
  std::fill(camera, camera + P, 1.0f);
  radiance_packet(scene, rays, none, smp, camera, n, 0, 1, counts, out);
}

}  // namespace tessera

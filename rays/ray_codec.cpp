#include "ray_codec.h"

#include <cfloat>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace tessera::rays {

namespace v1 = tessera::v1;

namespace {

// `field` holding exactly `count` values, uninitialized: the caller writes every one. Resize()
// would first zero what is then overwritten.
template <class T>
T* exactly(google::protobuf::RepeatedField<T>* field, size_t count) {
  field->Clear();
  field->Reserve(int(count));
  return field->AddNAlreadyReserved(int(count));
}

constexpr float kInf = std::numeric_limits<float>::infinity();

}  // namespace

std::optional<RayProblem> check_rays(const v1::TraceRequest& req) {
  const size_t n = size_t(req.directions_size()) / 3;
  auto length_problem = [&](const char* field, size_t got, size_t per_ray, bool optional) {
    return RayProblem{n, field,
                      std::string(field) + " has " + std::to_string(got) + " values; " +
                          std::to_string(n) + " rays (from directions) need " + std::to_string(n * per_ray) +
                          (optional ? " or none" : "")};
  };
  if (size_t(req.directions_size()) % 3 != 0) {
    return RayProblem{n, "directions",
                      "directions has " + std::to_string(req.directions_size()) + " values, not 3 per ray"};
  }
  if (size_t(req.origins_size()) != 3 * n) return length_problem("origins", size_t(req.origins_size()), 3, false);
  if (req.t_min_size() != 0 && size_t(req.t_min_size()) != n) return length_problem("t_min", size_t(req.t_min_size()), 1, true);
  if (req.t_max_size() != 0 && size_t(req.t_max_size()) != n) return length_problem("t_max", size_t(req.t_max_size()), 1, true);
  if (req.ids_size() != 0 && size_t(req.ids_size()) != n) return length_problem("ids", size_t(req.ids_size()), 1, true);
  const double* o = req.origins().data();
  const double* d = req.directions().data();
  const float* tmin = req.t_min_size() ? req.t_min().data() : nullptr;
  const float* tmax = req.t_max_size() ? req.t_max().data() : nullptr;
  // check_ray()'s rules, screened array by array with no branch (NaN fails every comparison;
  // RayCodec.CheckRaysNamesTheFirstBadRayAsCheckRayDoes): a good batch costs one read of its
  // arrays, no struct per ray. Only a batch with a bad ray pays for check_ray(), to name the
  // first one.
  bool ok = true;
  for (size_t k = 0; k < 3 * n; ++k) ok &= (std::abs(o[k]) <= kMaxOrigin) & (std::abs(d[k]) <= DBL_MAX);
  for (size_t i = 0; i < n; ++i) ok &= (d[3 * i] != 0.0) | (d[3 * i + 1] != 0.0) | (d[3 * i + 2] != 0.0);
  if (tmin) {
    for (size_t i = 0; i < n; ++i) ok &= (tmin[i] >= 0.0f) & (tmin[i] <= FLT_MAX);
  }
  if (tmin && tmax) {
    for (size_t i = 0; i < n; ++i) ok &= tmin[i] <= tmax[i];
  } else if (tmax) {
    for (size_t i = 0; i < n; ++i) ok &= tmax[i] >= 0.0f;  // t_min 0: not NaN, not below it
  }
  if (ok) return std::nullopt;
  for (size_t i = 0; i < n; ++i) {
    WorldRay r;
    read_rays(req, i, i + 1, &r);
    if (auto p = check_ray(r, i)) return p;
  }
  return std::nullopt;  // not reached: the screen fails only where check_ray() names a ray
}

void read_rays(const v1::TraceRequest& req, size_t begin, size_t end, WorldRay* out) {
  const double* o = req.origins().data();
  const double* d = req.directions().data();
  const float* tmin = req.t_min_size() ? req.t_min().data() : nullptr;
  const float* tmax = req.t_max_size() ? req.t_max().data() : nullptr;
  for (size_t i = begin; i < end; ++i) {
    WorldRay& r = out[i - begin];
    r.o = Vec3d(o[3 * i], o[3 * i + 1], o[3 * i + 2]);
    r.d = Vec3d(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
    r.tmin = tmin ? tmin[i] : 0.0f;
    r.tmax = tmax ? tmax[i] : kInf;
  }
}

void encode_rays(std::span<const WorldRay> rays, std::span<const uint64_t> ids, v1::TraceRequest* req) {
  const size_t n = rays.size();
  double* o = exactly(req->mutable_origins(), 3 * n);
  double* d = exactly(req->mutable_directions(), 3 * n);
  bool tmin = false, tmax = false;
  for (size_t i = 0; i < n; ++i) {
    const WorldRay& r = rays[i];
    for (int k = 0; k < 3; ++k) {
      o[3 * i + k] = r.o[k];
      d[3 * i + k] = r.d[k];
    }
    tmin |= r.tmin != 0.0f;
    tmax |= r.tmax != kInf;
  }
  req->clear_t_min();
  req->clear_t_max();
  if (tmin) {
    float* t = exactly(req->mutable_t_min(), n);
    for (size_t i = 0; i < n; ++i) t[i] = rays[i].tmin;
  }
  if (tmax) {
    float* t = exactly(req->mutable_t_max(), n);
    for (size_t i = 0; i < n; ++i) t[i] = rays[i].tmax;
  }
  req->mutable_ids()->Assign(ids.begin(), ids.end());
}

HitArrays::HitArrays(v1::TraceResponse* resp, size_t n, bool occlusion) : occlusion_(occlusion) {
  std::string* flags = resp->mutable_hit();
  flags->resize(n);
  hit_ = flags->data();
  if (occlusion) return;
  t_ = exactly(resp->mutable_t(), n);
  p_ = exactly(resp->mutable_points(), 3 * n);
  n_ = exactly(resp->mutable_normals(), 3 * n);
  ns_ = exactly(resp->mutable_shading_normals(), 3 * n);
  uv_ = exactly(resp->mutable_barycentrics(), 2 * n);
  object_ = exactly(resp->mutable_objects(), n);
  primitive_ = exactly(resp->mutable_primitives(), n);
  material_ = exactly(resp->mutable_materials(), n);
}

void HitArrays::write(size_t begin, std::span<const WorldHit> hits) const {
  for (size_t k = 0; k < hits.size(); ++k) hit_[begin + k] = hits[k].hit ? 1 : 0;
  if (occlusion_) return;
  for (size_t k = 0; k < hits.size(); ++k) {
    const WorldHit& h = hits[k];
    const size_t i = begin + k;
    t_[i] = h.t;
    for (int c = 0; c < 3; ++c) {
      p_[3 * i + c] = h.p[c];
      n_[3 * i + c] = h.n[c];
      ns_[3 * i + c] = h.ns[c];
    }
    uv_[2 * i] = h.u;
    uv_[2 * i + 1] = h.v;
    object_[i] = h.object;
    primitive_[i] = h.primitive;
    material_[i] = h.material;
  }
}

std::vector<WorldHit> decode_hits(const v1::TraceResponse& r, size_t n, bool occlusion) {
  auto need = [&](const char* field, size_t got, size_t per_ray) {
    if (got != per_ray * n) {
      throw std::runtime_error(std::string("response field ") + field + " has " + std::to_string(got) +
                               " values for " + std::to_string(n) + " rays");
    }
  };
  need("hit", r.hit().size(), 1);
  std::vector<WorldHit> hits(n);
  WorldHit* out = hits.data();
  const char* f = r.hit().data();
  if (occlusion) {
    for (size_t i = 0; i < n; ++i) out[i].hit = f[i] != 0;
    return hits;
  }
  need("t", size_t(r.t_size()), 1);
  need("points", size_t(r.points_size()), 3);
  need("normals", size_t(r.normals_size()), 3);
  need("shading_normals", size_t(r.shading_normals_size()), 3);
  need("barycentrics", size_t(r.barycentrics_size()), 2);
  need("objects", size_t(r.objects_size()), 1);
  need("primitives", size_t(r.primitives_size()), 1);
  need("materials", size_t(r.materials_size()), 1);
  const float *t = r.t().data(), *nn = r.normals().data(), *ns = r.shading_normals().data(),
              *uv = r.barycentrics().data();
  const double* p = r.points().data();
  const uint32_t *obj = r.objects().data(), *prim = r.primitives().data(), *mat = r.materials().data();
  // Through raw pointers: RepeatedField's operator[] is not free in a loop this hot.
  for (size_t i = 0; i < n; ++i) {
    WorldHit& h = out[i];
    h.hit = f[i] != 0;
    h.t = t[i];
    h.p = Vec3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    h.n = Vec3f(nn[3 * i], nn[3 * i + 1], nn[3 * i + 2]);
    h.ns = Vec3f(ns[3 * i], ns[3 * i + 1], ns[3 * i + 2]);
    h.u = uv[2 * i];
    h.v = uv[2 * i + 1];
    h.object = obj[i];
    h.primitive = prim[i];
    h.material = mat[i];
  }
  return hits;
}

}  // namespace tessera::rays

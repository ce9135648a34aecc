// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_codec.h"

#include <cfloat>
#include <cmath>
#include <limits>

#include "rays/rays_error.h"

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

std::string check_rays(const v1::TraceRequest& req) {
  const size_t n = size_t(req.directions_size()) / 3;
  auto length_problem = [&](const char* field, size_t got, size_t per_ray, bool optional) {
    return std::string(field) + " has " + std::to_string(got) + " values; " + std::to_string(n) +
           " rays (from directions) need " + std::to_string(n * per_ray) + (optional ? " or none" : "") +
           " (field " + field + ")";
  };
  if (size_t(req.directions_size()) % 3 != 0) {
    return "directions has " + std::to_string(req.directions_size()) + " values, not 3 per ray (field directions)";
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
  if (ok) return "";
  for (size_t i = 0; i < n; ++i) {
    WorldRay r;
    read_rays(req, i, i + 1, &r);
    std::string field;
    if (std::string p = check_ray(r, i, &field); !p.empty()) return p + " (field " + field + ")";
  }
  return "";  // not reached: the screen fails only where check_ray() names a ray
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

std::string read_fields(const v1::TraceRequest& req, HitFields* fields) {
  if (req.fields_size() == 0) {
    *fields = HitFields::all();
    return "";
  }
  HitFields asked;
  for (int k = 0; k < req.fields_size(); ++k) {
    // proto3 keeps numbers it does not know: a newer client's field reaches here as a number.
    const int value = req.fields(k);
    if (value >= 1 && value <= kHitFieldCount) {
      asked = asked.with(HitField(value - 1));
      continue;
    }
    std::string allowed;
    for (int v = 1; v <= kHitFieldCount; ++v) {
      allowed += (v > 1 ? ", " : "") + v1::HitField_Name(v1::HitField(v));
    }
    const std::string what = value == v1::HIT_FIELD_UNSPECIFIED ? "HIT_FIELD_UNSPECIFIED (0) names no field"
                                                               : std::to_string(value) + " is not a HitField";
    return "fields[" + std::to_string(k) + "]: " + what + " (allowed: " + allowed + ")";
  }
  *fields = asked;
  return "";
}

void encode_fields(HitFields fields, v1::TraceRequest* req) {
  req->clear_fields();
  if (fields == HitFields()) {
    throw RaysError("a field mask names one field at least (for `hit` alone, ask for occlusion)");
  }
  if (fields.is_all()) return;
  for (HitField f : fields.list()) req->add_fields(v1::HitField(int(f) + 1));
}

HitArrays::HitArrays(v1::TraceResponse* resp, size_t n, bool occlusion, HitFields fields) {
  std::string* flags = resp->mutable_hit();
  flags->resize(n);
  hit_ = flags->data();
  if (occlusion) return;
  if (fields.has(HitField::kT)) t_ = exactly(resp->mutable_t(), n);
  if (fields.has(HitField::kPoint)) p_ = exactly(resp->mutable_points(), 3 * n);
  if (fields.has(HitField::kNormal)) n_ = exactly(resp->mutable_normals(), 3 * n);
  if (fields.has(HitField::kShadingNormal)) ns_ = exactly(resp->mutable_shading_normals(), 3 * n);
  if (fields.has(HitField::kBarycentrics)) uv_ = exactly(resp->mutable_barycentrics(), 2 * n);
  if (fields.has(HitField::kObject)) object_ = exactly(resp->mutable_objects(), n);
  if (fields.has(HitField::kPrimitive)) primitive_ = exactly(resp->mutable_primitives(), n);
  if (fields.has(HitField::kMaterial)) material_ = exactly(resp->mutable_materials(), n);
}

void HitArrays::write(size_t begin, std::span<const WorldHit> hits) const {
  // One pass over the chunk's hits; the tests on arrays not asked for (all but the flags, for
  // occlusion) take the same branch for every ray, so they cost next to nothing.
  const HitColumns c = columns();
  for (size_t k = 0; k < hits.size(); ++k) write_hit(c, begin + k, hits[k]);
}

std::vector<WorldHit> decode_hits(const v1::TraceResponse& r, size_t n, bool occlusion, HitFields fields) {
  auto need = [&](const char* field, size_t got, size_t per_ray) {
    if (got != per_ray * n) {
      throw RaysError(std::string("response field ") + field + " has " + std::to_string(got) +
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
  // An asked array's data, its length checked; null for a field not asked for.
  auto asked = [&](HitField field, const char* name, const auto& array, size_t per_ray) {
    if (!fields.has(field)) return decltype(array.data())(nullptr);
    need(name, size_t(array.size()), per_ray);
    return array.data();
  };
  const float* t = asked(HitField::kT, "t", r.t(), 1);
  const double* p = asked(HitField::kPoint, "points", r.points(), 3);
  const float* nn = asked(HitField::kNormal, "normals", r.normals(), 3);
  const float* ns = asked(HitField::kShadingNormal, "shading_normals", r.shading_normals(), 3);
  const float* uv = asked(HitField::kBarycentrics, "barycentrics", r.barycentrics(), 2);
  const uint32_t* obj = asked(HitField::kObject, "objects", r.objects(), 1);
  const uint32_t* prim = asked(HitField::kPrimitive, "primitives", r.primitives(), 1);
  const uint32_t* mat = asked(HitField::kMaterial, "materials", r.materials(), 1);
  // Through raw pointers: RepeatedField's operator[] is not free in a loop this hot.
  for (size_t i = 0; i < n; ++i) {
    WorldHit& h = out[i];
    h.hit = f[i] != 0;
    if (t) h.t = t[i];
    if (p) h.p = Vec3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    if (nn) h.n = Vec3f(nn[3 * i], nn[3 * i + 1], nn[3 * i + 2]);
    if (ns) h.ns = Vec3f(ns[3 * i], ns[3 * i + 1], ns[3 * i + 2]);
    if (uv) {
      h.u = uv[2 * i];
      h.v = uv[2 * i + 1];
    }
    if (obj) h.object = obj[i];
    if (prim) h.primitive = prim[i];
    if (mat) h.material = mat[i];
  }
  return hits;
}

}  // namespace tessera::rays

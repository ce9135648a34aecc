#include "ray_codec.h"

#include <stdexcept>

namespace tessera::rays {

namespace v1 = tessera::v1;

std::optional<RayProblem> decode_rays(const v1::TraceRequest& req, std::vector<WorldRay>* rays) {
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
  rays->resize(n);
  const double* o = req.origins().data();
  const double* d = req.directions().data();
  const float* tmin = req.t_min_size() ? req.t_min().data() : nullptr;
  const float* tmax = req.t_max_size() ? req.t_max().data() : nullptr;
  for (size_t i = 0; i < n; ++i) {
    WorldRay& r = (*rays)[i];
    r.o = Vec3d(o[3 * i], o[3 * i + 1], o[3 * i + 2]);
    r.d = Vec3d(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
    r.tmin = tmin ? tmin[i] : 0.0f;
    r.tmax = tmax ? tmax[i] : std::numeric_limits<float>::infinity();
    if (auto p = check_ray(r, i)) return p;
  }
  return std::nullopt;
}

void encode_rays(const std::vector<WorldRay>& rays, const std::vector<uint64_t>& ids, v1::TraceRequest* req) {
  const int n = int(rays.size());
  // Resize then fill through the raw arrays: no per-element capacity checks.
  req->mutable_origins()->Resize(3 * n, 0.0);
  req->mutable_directions()->Resize(3 * n, 0.0);
  double* o = req->mutable_origins()->mutable_data();
  double* d = req->mutable_directions()->mutable_data();
  bool tmin = false, tmax = false;
  for (int i = 0; i < n; ++i) {
    const WorldRay& r = rays[size_t(i)];
    for (int k = 0; k < 3; ++k) {
      o[3 * i + k] = r.o[k];
      d[3 * i + k] = r.d[k];
    }
    tmin = tmin || r.tmin != 0.0f;
    tmax = tmax || r.tmax != std::numeric_limits<float>::infinity();
  }
  if (tmin) {
    for (const WorldRay& r : rays) req->add_t_min(r.tmin);
  }
  if (tmax) {
    for (const WorldRay& r : rays) req->add_t_max(r.tmax);
  }
  for (uint64_t id : ids) req->add_ids(id);
}

void encode_hits(const std::vector<WorldHit>& hits, bool occlusion, v1::TraceResponse* resp) {
  const int n = int(hits.size());
  std::string* flags = resp->mutable_hit();
  flags->resize(size_t(n));
  for (int i = 0; i < n; ++i) (*flags)[size_t(i)] = hits[size_t(i)].hit ? 1 : 0;
  if (occlusion) return;
  // Resize then fill: one allocation per array, no per-element capacity checks.
  auto sized = [n](auto* field, int per_ray) {
    field->Resize(per_ray * n, 0);
    return field->mutable_data();
  };
  float* t = sized(resp->mutable_t(), 1);
  double* p = sized(resp->mutable_points(), 3);
  float* nn = sized(resp->mutable_normals(), 3);
  float* ns = sized(resp->mutable_shading_normals(), 3);
  float* uv = sized(resp->mutable_barycentrics(), 2);
  uint32_t* obj = sized(resp->mutable_objects(), 1);
  uint32_t* prim = sized(resp->mutable_primitives(), 1);
  uint32_t* mat = sized(resp->mutable_materials(), 1);
  for (int i = 0; i < n; ++i) {
    const WorldHit& h = hits[size_t(i)];
    t[i] = h.t;
    for (int k = 0; k < 3; ++k) {
      p[3 * i + k] = h.p[k];
      nn[3 * i + k] = h.n[k];
      ns[3 * i + k] = h.ns[k];
    }
    uv[2 * i] = h.u;
    uv[2 * i + 1] = h.v;
    obj[i] = h.object;
    prim[i] = h.primitive;
    mat[i] = h.material;
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
  for (size_t i = 0; i < n; ++i) hits[i].hit = r.hit()[i] != 0;
  if (occlusion) return hits;
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
  for (size_t i = 0; i < n; ++i) {
    WorldHit& h = hits[i];
    h.t = t[i];
    h.p = Vec3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    h.n = Vec3f(nn[3 * i], nn[3 * i + 1], nn[3 * i + 2]);
    h.ns = Vec3f(ns[3 * i], ns[3 * i + 1], ns[3 * i + 2]);
    h.u = uv[2 * i];
    h.v = uv[2 * i + 1];
    h.object = r.objects()[int(i)];
    h.primitive = r.primitives()[int(i)];
    h.material = r.materials()[int(i)];
  }
  return hits;
}

}  // namespace tessera::rays

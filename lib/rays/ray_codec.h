// SPDX-License-Identifier: Apache-2.0
// Rays and hits to and from the packed arrays of tessera.v1.TraceRequest / TraceResponse
// (proto/tessera/v1/ray_service.proto). Shared by the ray server and the `tessera rays` client.
// The service's cost per ray is mostly copies, so none is made twice: arrays are sized once and
// filled through their raw pointers, and the server decodes, traces and encodes a batch a chunk
// at a time (check_rays, read_rays, HitArrays) rather than through batch-sized struct arrays.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rays/hit_fields.h"
#include "rays/ray_check.h"
#include "rays/rays_error.h"
#include "rays/world_ray.h"
#include "tessera/v1/ray_service.pb.h"

namespace tessera::rays {

// "" for a good request, else its first problem, ending with the field at fault: array lengths
// that disagree ("... (field origins)", "t_min", ...), then check_ray() per ray ("ray 3:
// direction is not finite (field direction)"). Nothing is copied: a good batch costs one read
// of its arrays.
std::string check_rays(const tessera::v1::TraceRequest& req);
// Rays [begin, end) of a request that check_rays() accepted.
void read_rays(const tessera::v1::TraceRequest& req, size_t begin, size_t end, WorldRay* out);
// `ids` empty or one per ray. t_min/t_max are sent only when some ray needs them.
void encode_rays(std::span<const WorldRay> rays, std::span<const uint64_t> ids, tessera::v1::TraceRequest* req);

// The request's field mask (`fields`; empty: every field) into `*fields` and "", or the problem
// with it: "fields[k]: ..." for HIT_FIELD_UNSPECIFIED or a number this server does not know,
// with the allowed names.
std::string read_fields(const tessera::v1::TraceRequest& req, HitFields* fields);
// Sets the request's mask: nothing for every field (today's requests, and fewer bytes). `fields`
// names one at least (an empty mask means every field; a client that wants only `hit` asks for
// occlusion): throws RaysError otherwise.
void encode_fields(HitFields fields, tessera::v1::TraceRequest* req);

// Where a response's hits go: its arrays, sized for a batch by the constructor (uninitialized,
// capacity kept: a response reused between batches does not allocate again), filled by write()
// in any order of disjoint ranges (from several threads at once). Occlusion: the flags only;
// otherwise the flags and the arrays of `fields` (the others are neither sized nor written:
// the caller passes a cleared response, and they go out empty).
class HitArrays {
 public:
  HitArrays(tessera::v1::TraceResponse* resp, size_t n, bool occlusion, HitFields fields = HitFields::all());
  // hits[i] is ray begin + i's.
  void write(size_t begin, std::span<const WorldHit> hits) const;
  // The asked arrays (null where not asked), for RayTracer::nearest_into to fill directly.
  HitColumns columns() const { return {hit_, t_, p_, n_, ns_, uv_, object_, primitive_, material_}; }

 private:
  // Null for a field not asked for (every one but the flags, for occlusion).
  char* hit_;
  float *t_ = nullptr, *n_ = nullptr, *ns_ = nullptr, *uv_ = nullptr;
  double* p_ = nullptr;
  uint32_t *object_ = nullptr, *primitive_ = nullptr, *material_ = nullptr;
};

// The hits of an answer to a request with the mask `fields`: those fields and `hit` are filled,
// the others keep WorldHit's defaults (arrays the mask left out are not read, so a server that
// sends them anyway, one older than the mask, is fine). Throws RaysError when an asked
// array does not hold `n` rays' worth.
std::vector<WorldHit> decode_hits(const tessera::v1::TraceResponse& resp, size_t n, bool occlusion,
                                  HitFields fields = HitFields::all());

}  // namespace tessera::rays

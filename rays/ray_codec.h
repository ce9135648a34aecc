// Rays and hits to and from the packed arrays of tessera.v1.TraceRequest / TraceResponse
// (proto/tessera/v1/ray_service.proto). Shared by the ray server and the `tessera rays` client.
// The service's cost per ray is mostly copies, so none is made twice: arrays are sized once and
// filled through their raw pointers, and the server decodes, traces and encodes a batch a chunk
// at a time (check_rays, read_rays, HitArrays) rather than through batch-sized struct arrays.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rays/ray_check.h"
#include "rays/world_ray.h"
#include "tessera/v1/ray_service.pb.h"

namespace tessera::rays {

// The request's first problem, or nothing: array lengths that disagree (field "origins",
// "t_min", ...; index = the number of rays the directions imply), then check_ray() per ray.
// Nothing is copied: a good batch costs one read of its arrays.
std::optional<RayProblem> check_rays(const tessera::v1::TraceRequest& req);
// Rays [begin, end) of a request that check_rays() accepted.
void read_rays(const tessera::v1::TraceRequest& req, size_t begin, size_t end, WorldRay* out);
// `ids` empty or one per ray. t_min/t_max are sent only when some ray needs them.
void encode_rays(std::span<const WorldRay> rays, std::span<const uint64_t> ids, tessera::v1::TraceRequest* req);

// Where a response's hits go: its arrays, sized for a batch by the constructor (uninitialized,
// capacity kept: a response reused between batches does not allocate again), filled by write()
// in any order of disjoint ranges (from several threads at once). Occlusion: the flags only.
class HitArrays {
 public:
  HitArrays(tessera::v1::TraceResponse* resp, size_t n, bool occlusion);
  // hits[i] is ray begin + i's.
  void write(size_t begin, std::span<const WorldHit> hits) const;

 private:
  bool occlusion_;
  char* hit_;
  float *t_ = nullptr, *n_ = nullptr, *ns_ = nullptr, *uv_ = nullptr;
  double* p_ = nullptr;
  uint32_t *object_ = nullptr, *primitive_ = nullptr, *material_ = nullptr;
};

// Throws std::runtime_error when the arrays do not hold `n` rays' worth.
std::vector<WorldHit> decode_hits(const tessera::v1::TraceResponse& resp, size_t n, bool occlusion);

}  // namespace tessera::rays

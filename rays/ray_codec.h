// Rays and hits to and from the packed arrays of tessera.v1.TraceRequest / TraceResponse
// (proto/tessera/v1/ray_service.proto). Shared by the ray server and the `tessera rays` client.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "rays/ray_check.h"
#include "rays/world_ray.h"
#include "tessera/v1/ray_service.pb.h"

namespace tessera::rays {

// The request's rays, or the first problem: array lengths that disagree (field "origins",
// "t_min", ...; index = the number of rays the directions imply), then check_ray() per ray.
std::optional<RayProblem> decode_rays(const tessera::v1::TraceRequest& req, std::vector<WorldRay>* rays);
// `ids` empty or one per ray. t_min/t_max are sent only when some ray needs them.
void encode_rays(const std::vector<WorldRay>& rays, const std::vector<uint64_t>& ids, tessera::v1::TraceRequest* req);

void encode_hits(const std::vector<WorldHit>& hits, bool occlusion, tessera::v1::TraceResponse* resp);
// Throws std::runtime_error when the arrays do not hold `n` rays' worth.
std::vector<WorldHit> decode_hits(const tessera::v1::TraceResponse& resp, size_t n, bool occlusion);

}  // namespace tessera::rays

// A batch traced on the calling TBB arena's threads, in chunks: the same bits as one serial
// call (a ray's answer depends on that ray alone, see RayTracer). Shared by the ray server and
// `tessera rays`.
#pragma once

#include <vector>

#include "rays/ray_tracer.h"

namespace tessera::rays {

// Batches up to this size are traced serially on the calling thread.
inline constexpr size_t kParallelBatch = 2048;

// hits->size() becomes rays.size(). `occlusion`: RayTracer::occluded, else nearest.
void trace_batch(const RayTracer& tracer, const std::vector<WorldRay>& rays, bool occlusion,
                 std::vector<WorldHit>* hits);

}  // namespace tessera::rays

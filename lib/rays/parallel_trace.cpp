// SPDX-License-Identifier: Apache-2.0
#include "rays/parallel_trace.h"

namespace tessera::rays {

void trace_batch(const RayTracer& tracer, const std::vector<WorldRay>& rays, bool occlusion,
                 std::vector<WorldHit>* hits) {
  hits->resize(rays.size());
  for_each_chunk(rays.size(), [&](size_t begin, size_t end) {
    if (occlusion) tracer.occluded(rays.data() + begin, end - begin, hits->data() + begin);
    else tracer.nearest(rays.data() + begin, end - begin, hits->data() + begin);
  });
}

}  // namespace tessera::rays

#include "rays/parallel_trace.h"

#include <tbb/parallel_for.h>

#include <algorithm>

namespace tessera::rays {

namespace {

// Rays per task: ~0.2-1 ms of work, so scheduling costs nothing.
constexpr size_t kChunk = kParallelBatch / 2;

}  // namespace

void trace_batch(const RayTracer& tracer, const std::vector<WorldRay>& rays, bool occlusion,
                 std::vector<WorldHit>* hits) {
  hits->resize(rays.size());
  auto run = [&](size_t begin, size_t end) {
    if (occlusion) tracer.occluded(rays.data() + begin, end - begin, hits->data() + begin);
    else tracer.nearest(rays.data() + begin, end - begin, hits->data() + begin);
  };
  if (rays.size() <= kParallelBatch) {
    run(0, rays.size());
    return;
  }
  tbb::parallel_for(size_t(0), (rays.size() + kChunk - 1) / kChunk,
                    [&](size_t c) { run(c * kChunk, std::min(rays.size(), (c + 1) * kChunk)); });
}

}  // namespace tessera::rays

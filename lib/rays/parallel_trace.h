// SPDX-License-Identifier: Apache-2.0
// A batch traced on the calling TBB arena's threads, in chunks: the same bits as one serial
// call (a ray's answer depends on that ray alone, see RayTracer). Shared by the ray server and
// `tessera rays`.
#pragma once

#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

#include "rays/ray_tracer.h"

namespace tessera::rays {

// Batches up to this size are traced serially on the calling thread.
inline constexpr size_t kParallelBatch = 2048;
// Rays per chunk: ~0.1-1 ms of tracing, so scheduling a parallel chunk costs nothing, and a
// chunk's rays and hits (~128 KiB) stay in the core's L2 cache between decoding, tracing and
// encoding.
inline constexpr size_t kChunk = kParallelBatch / 2;

// f(begin, end) over [0, n) in chunks of at most kChunk rays: in order on the calling thread for
// n <= kParallelBatch, else in parallel on the calling arena (chunks then run in any order).
template <class F>
void for_each_chunk(size_t n, F&& f) {
  if (n <= kParallelBatch) {
    for (size_t begin = 0; begin < n; begin += kChunk) f(begin, std::min(n, begin + kChunk));
    return;
  }
  tbb::parallel_for(size_t(0), (n + kChunk - 1) / kChunk,
                    [&](size_t c) { f(c * kChunk, std::min(n, (c + 1) * kChunk)); });
}

// hits->size() becomes rays.size(). `occlusion`: RayTracer::occluded, else nearest.
void trace_batch(const RayTracer& tracer, const std::vector<WorldRay>& rays, bool occlusion,
                 std::vector<WorldHit>* hits);

}  // namespace tessera::rays

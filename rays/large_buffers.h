// SPDX-License-Identifier: Apache-2.0
// Batches of 65,536 rays are multi-MiB messages: glibc serves such allocations with fresh mmap()s
// and unmaps them on free, so every request paid a page fault per 4 KiB of its buffers
// (measured in bench/rays: 65,536-ray calls ran at 60 % of the rate of 4,096-ray ones). Keeping
// them on the heap instead lets the next request reuse the pages.
#pragma once

#include <malloc.h>

namespace tessera::rayserver {

// Call once at startup, before threads: allocations up to 256 MiB come from the heap, and the
// heap is trimmed only when 1 GiB is free at its top.
inline void keep_large_buffers() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

}  // namespace tessera::rayserver

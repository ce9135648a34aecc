// SPDX-License-Identifier: Apache-2.0
// An allocator for a frame's large working arrays (a frame target's per-pixel estimates, the
// lattice's corners): it asks the kernel to back them with transparent huge pages.
//
// Why: such an array is written once a pixel and freed with the frame, so each of its 4 KiB pages
// costs one page fault, and a 1920x1080 frame target keeps 166 MB of estimates. On a KVM guest a
// fault costs about 15 us, and the faults were about 30% of that frame's time (docs/performance.md,
// "Large frames and page faults"). With 2 MiB pages there are 512 times fewer. Neither the C++
// library nor glibc's malloc offers this per allocation (glibc's malloc.hugetlb tunable applies
// to the whole process and is read only at start), hence this allocator.
//
// Below kHugePageMinBytes it is std::allocator. Where the kernel's transparent huge pages are
// "never", madvise fails and the memory is the same as std::allocator's; where "always", the
// advice changes nothing.
#pragma once

#include <sys/mman.h>

#include <cstddef>
#include <cstdlib>
#include <memory>
#include <new>

namespace tessera {

inline constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;
inline constexpr std::size_t kHugePageMinBytes = 2 * kHugePageBytes;

template <class T>
struct HugePageAllocator {
  using value_type = T;

  HugePageAllocator() = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHugePageMinBytes) return std::allocator<T>().allocate(n);
    const std::size_t rounded = (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
    void* p = std::aligned_alloc(kHugePageBytes, rounded);
    if (p == nullptr) throw std::bad_alloc();
    // Advice only: where it is refused the pages are ordinary ones.
    madvise(p, rounded, MADV_HUGEPAGE);
    return static_cast<T*>(p);
  }

  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < kHugePageMinBytes) {
      std::allocator<T>().deallocate(p, n);
    } else {
      std::free(p);
    }
  }

  template <class U>
  bool operator==(const HugePageAllocator<U>&) const noexcept {
    return true;
  }
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// HugePageAllocator: large arrays are aligned to a huge page, zeroed like std::vector's, and backed
// by transparent huge pages where the kernel offers them; small ones are std::allocator's.
#include "render/huge_page_allocator.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace tessera {
namespace {

// The kernel's transparent huge page mode: "always", "madvise", "never", or "" when unknown.
std::string thp_mode() {
  std::ifstream in("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  std::getline(in, line);
  const size_t open = line.find('['), close = line.find(']');
  return open == std::string::npos || close == std::string::npos ? "" : line.substr(open + 1, close - open - 1);
}

// AnonHugePages (kB) of the mapping that holds address p, from /proc/self/smaps; -1 if not found.
long anon_huge_kb(const void* p) {
  std::ifstream in("/proc/self/smaps");
  const auto at = reinterpret_cast<uintptr_t>(p);
  bool inside = false;
  for (std::string line; std::getline(in, line);) {
    uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= at && at < hi;
      continue;
    }
    if (inside && line.rfind("AnonHugePages:", 0) == 0) return std::stol(line.substr(14));
  }
  return -1;
}

TEST(HugePageAllocator, LargeArraysAreAlignedZeroedAndOnHugePages) {
  const size_t n = (16u << 20) / sizeof(uint64_t);  // 16 MiB
  std::vector<uint64_t, HugePageAllocator<uint64_t>> v(n);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(v.data()) % kHugePageBytes, 0u);
  for (size_t i = 0; i < n; i += 4096) ASSERT_EQ(v[i], 0u) << i;
  std::iota(v.begin(), v.end(), uint64_t(1));
  EXPECT_EQ(v.back(), uint64_t(n));
  const std::string mode = thp_mode();
#if defined(__SANITIZE_ADDRESS__)
  const bool own_malloc = false;  // AddressSanitizer's allocator maps the memory its own way
#else
  const bool own_malloc = true;
#endif
  if (own_malloc && (mode == "always" || mode == "madvise")) {
    // Every page written: the advice must have given at least one huge page.
    EXPECT_GT(anon_huge_kb(v.data()), 0) << "transparent huge pages are '" << mode << "' here";
  }
  v.resize(n / 2);
  v.shrink_to_fit();  // freed and allocated again through the allocator
  EXPECT_EQ(v.back(), uint64_t(n / 2));
}

TEST(HugePageAllocator, SmallArraysAreOrdinary) {
  std::vector<int, HugePageAllocator<int>> v(1000, 7);
  EXPECT_EQ(std::accumulate(v.begin(), v.end(), 0), 7000);
  EXPECT_TRUE(HugePageAllocator<int>() == HugePageAllocator<double>());
}

}  // namespace
}  // namespace tessera

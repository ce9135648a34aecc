// SPDX-License-Identifier: Apache-2.0
#include "cpu_quota.h"

#include <gtest/gtest.h>
#include <sched.h>

#include <thread>

namespace tessera::worker {
namespace {

TEST(CpuQuota, CgroupV2CpuMaxRoundsUp) {
  EXPECT_EQ(cores_from_cpu_max("200000 100000"), 2);
  EXPECT_EQ(cores_from_cpu_max("150000 100000"), 2);  // 1.5 CPUs: two threads, throttled a little
  EXPECT_EQ(cores_from_cpu_max("50000 100000"), 1);   // half a CPU still gets one thread
  EXPECT_EQ(cores_from_cpu_max("400000 100000\n"), 4);
}

TEST(CpuQuota, UnlimitedOrMalformedMeansNoLimit) {
  EXPECT_EQ(cores_from_cpu_max("max 100000"), std::nullopt);
  EXPECT_EQ(cores_from_cpu_max(""), std::nullopt);
  EXPECT_EQ(cores_from_cpu_max("abc 100000"), std::nullopt);
  EXPECT_EQ(cores_from_cpu_max("100000 0"), std::nullopt);
  EXPECT_EQ(cores_from_cfs(-1, 100000), std::nullopt);
  EXPECT_EQ(cores_from_cfs(300000, 100000), 3);
}

TEST(CpuQuota, AvailableCoresRespectsAffinity) {
  cpu_set_t old_set;
  ASSERT_EQ(sched_getaffinity(0, sizeof old_set, &old_set), 0);
  const int before = available_cores();
  EXPECT_GE(before, 1);
  EXPECT_LE(before, int(std::max(1u, std::thread::hardware_concurrency())));
  // Pin this thread to one CPU (the first one it may use): the answer must drop to 1.
  cpu_set_t one;
  CPU_ZERO(&one);
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &old_set)) { CPU_SET(c, &one); break; }
  ASSERT_EQ(sched_setaffinity(0, sizeof one, &one), 0);
  EXPECT_EQ(available_cores(), 1);
  ASSERT_EQ(sched_setaffinity(0, sizeof old_set, &old_set), 0);
}

}  // namespace
}  // namespace tessera::worker

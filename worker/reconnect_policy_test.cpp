// SPDX-License-Identifier: Apache-2.0
#include "reconnect_policy.h"

#include <gtest/gtest.h>

#include <vector>

namespace tessera::worker {
namespace {

using std::chrono::milliseconds;

TEST(ReconnectPolicyTest, RefusedSessionsDoubleTheWaitUpToTheCap) {
  ReconnectPolicy p(milliseconds(200), milliseconds(10000));
  std::vector<int64_t> waits;
  for (int i = 0; i < 9; ++i) waits.push_back(p.next_wait(false, 1.0).count());
  EXPECT_EQ(waits, (std::vector<int64_t>{200, 400, 800, 1600, 3200, 6400, 10000, 10000, 10000}));
}

TEST(ReconnectPolicyTest, AnAcceptedSessionStartsTheBackoffOver) {
  ReconnectPolicy p(milliseconds(200), milliseconds(10000));
  for (int i = 0; i < 5; ++i) p.next_wait(false, 1.0);
  EXPECT_EQ(p.next_wait(true, 1.0).count(), 200);   // the session before this wait was accepted
  EXPECT_EQ(p.next_wait(false, 1.0).count(), 400);  // and the doubling resumes from there
}

TEST(ReconnectPolicyTest, JitterScalesEachWaitWithinItsBounds) {
  ReconnectPolicy low(milliseconds(1000), milliseconds(10000)), high(milliseconds(1000), milliseconds(10000));
  EXPECT_EQ(low.next_wait(false, ReconnectPolicy::kMinJitter).count(), 800);
  EXPECT_EQ(high.next_wait(false, 1.19).count(), 1190);
  // The jitter does not feed back into the schedule: the next base wait is 2 s for both.
  EXPECT_EQ(low.next_wait(false, 1.0).count(), 2000);
  EXPECT_EQ(high.next_wait(false, 1.0).count(), 2000);
}

TEST(ReconnectPolicyTest, WaitsOutARefusalButNotAnAbsentCoordinator) {
  EXPECT_EQ(ReconnectPolicy::how_to_wait(true), ReconnectPolicy::Wait::kFullBackoff);
  EXPECT_EQ(ReconnectPolicy::how_to_wait(false), ReconnectPolicy::Wait::kUntilCoordinatorListens);
}

}  // namespace
}  // namespace tessera::worker

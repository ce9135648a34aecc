// SPDX-License-Identifier: Apache-2.0
// The undelivered-frame ledger: totals, the oldest frame, per-job removal.
#include "undelivered_frames.h"

#include <gtest/gtest.h>

namespace tessera::server {
namespace {

using namespace std::chrono_literals;

TEST(UndeliveredFramesTest, CountsFramesBytesAndTheOldestUntilDelivered) {
  UndeliveredFrames u;
  const TimePoint t0{};
  EXPECT_EQ(u.oldest(), std::nullopt);
  u.add("j", 1, 100, t0 + 5s);
  u.add("k", 7, 40, t0 + 2s);
  u.add("j", 2, 10, t0 + 9s);
  u.add("j", 2, 999, t0 + 1s);  // a second report of the same frame changes nothing
  EXPECT_EQ(u.frames(), 3u);
  EXPECT_EQ(u.bytes(), 150u);
  EXPECT_EQ(u.oldest(), t0 + 2s);
  EXPECT_EQ(u.jobs_oldest_first(), (std::vector<JobId>{"k", "j"}));
  u.remove("k", 7);
  EXPECT_EQ(u.oldest(), t0 + 5s);
  EXPECT_FALSE(u.holds("k"));
  EXPECT_TRUE(u.holds("j"));
  u.remove("k", 7);  // twice: nothing
  EXPECT_EQ(u.bytes(), 110u);
  u.forget("j");
  EXPECT_EQ(u.frames(), 0u);
  EXPECT_EQ(u.bytes(), 0u);
  EXPECT_FALSE(u.holds("j"));
  EXPECT_EQ(u.oldest(), std::nullopt);
}

TEST(UndeliveredFramesTest, ForgettingAJobLeavesJobsWithSimilarNamesAlone) {
  UndeliveredFrames u;
  u.add("ab", 1, 1, TimePoint{});
  u.add("a", 1, 2, TimePoint{});
  u.add("abc", -3, 4, TimePoint{});
  u.forget("ab");
  EXPECT_EQ(u.bytes(), 6u);
  EXPECT_TRUE(u.holds("a"));
  EXPECT_TRUE(u.holds("abc"));
}

}  // namespace
}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "watch_reattach.h"

#include <gtest/gtest.h>

#include <chrono>

namespace tessera::cli {
namespace {

using Code = grpc::StatusCode;
using std::chrono::seconds;

TEST(WatchReattach, AFinalStateOnACleanStreamFinishes) {
  ReattachPolicy p;
  EXPECT_EQ(p.after_stream(Code::OK, /*ended=*/true, /*seen=*/true), StreamEnd::kFinished);
  EXPECT_EQ(p.attempts(), 0);
}

TEST(WatchReattach, AnUnknownOrMalformedJobIsTheUsersInput) {
  ReattachPolicy p;
  EXPECT_EQ(p.after_stream(Code::NOT_FOUND, false, false), StreamEnd::kBadInput);
  EXPECT_EQ(p.after_stream(Code::INVALID_ARGUMENT, false, true), StreamEnd::kBadInput);
  EXPECT_EQ(p.attempts(), 0);
}

TEST(WatchReattach, ALostCoordinatorMidJobIsReattached) {
  ReattachPolicy p;
  EXPECT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kReattach);
  EXPECT_EQ(p.attempts(), 1);
  // A stream closed cleanly before the final state counts as lost too.
  EXPECT_EQ(p.after_stream(Code::OK, false, true), StreamEnd::kReattach);
  EXPECT_EQ(p.attempts(), 2);
}

TEST(WatchReattach, NoReattachBeforeTheJobWasEverSeen) {
  // The first stream never delivered the job's status: nothing to carry on with.
  ReattachPolicy p;
  EXPECT_EQ(p.after_stream(Code::UNAVAILABLE, false, false), StreamEnd::kGiveUp);
  EXPECT_EQ(p.after_stream(Code::OK, false, false), StreamEnd::kGiveUp);
  EXPECT_EQ(p.attempts(), 0);
}

TEST(WatchReattach, OtherFailuresAreNotRetried) {
  for (Code c : {Code::UNAUTHENTICATED, Code::PERMISSION_DENIED, Code::DEADLINE_EXCEEDED, Code::INTERNAL,
                 Code::CANCELLED, Code::RESOURCE_EXHAUSTED, Code::UNKNOWN}) {
    ReattachPolicy p;
    EXPECT_EQ(p.after_stream(c, false, true), StreamEnd::kGiveUp) << int(c);
    EXPECT_EQ(p.after_stream(c, true, true), StreamEnd::kGiveUp) << int(c);
  }
}

TEST(WatchReattach, WaitGrowsASecondAnAttemptUpToFive) {
  EXPECT_EQ(ReattachPolicy::kPause, std::chrono::milliseconds(100));
  ReattachPolicy p;
  EXPECT_EQ(p.wait(), seconds(0));
  const int expected[] = {1, 2, 3, 4, 5, 5, 5};
  for (int want : expected) {
    ASSERT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kReattach);
    EXPECT_EQ(p.wait(), seconds(want)) << "attempt " << p.attempts();
  }
}

TEST(WatchReattach, GivesUpAfterThirtyLossesInARow) {
  ReattachPolicy p;
  for (int i = 1; i <= 30; ++i) {
    ASSERT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kReattach) << "attempt " << i;
  }
  EXPECT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kGiveUp);
  EXPECT_EQ(p.attempts(), 30);
  // A final state still finishes, and a refused job is still the user's input.
  EXPECT_EQ(p.after_stream(Code::OK, true, true), StreamEnd::kFinished);
  EXPECT_EQ(p.after_stream(Code::NOT_FOUND, false, true), StreamEnd::kBadInput);
}

TEST(WatchReattach, EachReattachStartsTheCountAgain) {
  // A coordinator that restarts many times over a long job costs one attempt each time.
  ReattachPolicy p;
  for (int restart = 0; restart < 100; ++restart) {
    ASSERT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kReattach) << "restart " << restart;
    p.attached();
  }
  for (int i = 1; i <= 29; ++i) ASSERT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kReattach);
  p.attached();
  EXPECT_EQ(p.attempts(), 0);
  EXPECT_EQ(p.after_stream(Code::UNAVAILABLE, false, true), StreamEnd::kReattach);
  EXPECT_EQ(p.wait(), seconds(1));  // the backoff starts over as well
}

}  // namespace
}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
// Delivery leases: one holder a frame, fewest-frames first, a dead deliverer's frames free, an
// overdue frame moved to another deliverer (or kept when there is none).
#include "delivery_leases.h"

#include <gtest/gtest.h>

namespace tessera::server {
namespace {

using namespace std::chrono_literals;

int streams[3];  // three distinct addresses: the deliverers' identities
const DeliveryLeases::Deliverer A = &streams[0], B = &streams[1], C = &streams[2];

TEST(DeliveryLeasesTest, AFrameHasOneHolderAndFramesGoToTheLeastLoadedDeliverer) {
  DeliveryLeases d(60s);
  EXPECT_EQ(d.assign("j", 1), nullptr) << "no deliverer attached: nobody holds the frame";
  d.add("j", A);
  d.add("j", B);
  EXPECT_TRUE(d.delivers("j", A));
  EXPECT_FALSE(d.delivers("k", A));
  EXPECT_EQ(d.assign("j", 1), A);
  EXPECT_EQ(d.assign("j", 2), B);
  EXPECT_EQ(d.assign("j", 3), A);
  EXPECT_EQ(d.assign("j", 1), A) << "a held frame keeps its holder";
  EXPECT_EQ(d.holder("j", 2), B);
  EXPECT_EQ(d.holder("j", 9), nullptr);
  d.acknowledged("j", 1);
  EXPECT_EQ(d.holder("j", 1), nullptr);
  EXPECT_EQ(d.assign("j", 4), B) << "A holds one frame (3), B one (2): the one given a frame longest ago, B";
}

TEST(DeliveryLeasesTest, DeliverersThatFinishEachFrameBeforeTheNextTakeTurns) {
  // A slow job: each frame is written and acknowledged before the next one starts, so every
  // deliverer holds nothing when a frame is given out. They take turns instead of the first one
  // taking everything.
  DeliveryLeases d(60s);
  d.add("j", A);
  d.add("j", B);
  d.add("j", C);
  std::vector<DeliveryLeases::Deliverer> got;
  for (int f = 0; f < 6; ++f) {
    got.push_back(d.assign("j", f));
    d.acknowledged("j", f);
  }
  EXPECT_EQ(got, (std::vector<DeliveryLeases::Deliverer>{A, B, C, A, B, C}));
}

TEST(DeliveryLeasesTest, ADeliverersFramesAreFreedWhenItGoesAndTakenByTheOthers) {
  DeliveryLeases d(60s);
  d.add("j", A);
  d.add("j", B);
  d.assign("j", 1);
  d.assign("j", 2);
  d.assign("j", 3);
  const std::vector<int> freed = d.remove("j", A);
  EXPECT_EQ(freed, (std::vector<int>{1, 3}));
  EXPECT_EQ(d.holder("j", 1), nullptr);
  EXPECT_FALSE(d.delivers("j", A));
  EXPECT_EQ(d.assign("j", 1), B);
  d.remove("j", B);
  EXPECT_FALSE(d.has_deliverers("j"));
  EXPECT_EQ(d.assign("j", 1), nullptr);
}

TEST(DeliveryLeasesTest, AFrameSentWholeAndNotAcknowledgedWithinTheLeaseMovesToAnotherDeliverer) {
  DeliveryLeases d(60s);
  const TimePoint t0{};
  d.add("j", A);
  d.add("j", B);
  d.assign("j", 1);  // A
  EXPECT_TRUE(d.expire(t0 + 1h).empty()) << "a frame still arriving has no deadline";
  d.sent_whole("j", 1, t0);
  EXPECT_TRUE(d.expire(t0 + 59s).empty());
  auto moved = d.expire(t0 + 60s);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0].from, A);
  EXPECT_EQ(moved[0].to, B);
  EXPECT_EQ(d.holder("j", 1), B);
  EXPECT_TRUE(d.expire(t0 + 10h).empty()) << "the new holder's lease starts when it has the frame whole";
  d.sent_whole("j", 1, t0 + 61s);
  d.remove("j", A);
  moved = d.expire(t0 + 121s);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0].to, nullptr) << "no other deliverer: the frame stays with its holder";
  EXPECT_EQ(d.holder("j", 1), B);
  EXPECT_TRUE(d.expire(t0 + 150s).empty()) << "and its lease starts again";
  d.acknowledged("j", 1);
  EXPECT_TRUE(d.expire(t0 + 10h).empty());
}

TEST(DeliveryLeasesTest, JobsAreIndependentAndForgottenWhole) {
  DeliveryLeases d(60s);
  d.add("j", A);
  d.add("k", C);
  EXPECT_EQ(d.assign("j", 1), A);
  EXPECT_EQ(d.assign("k", 1), C);
  d.forget("j");
  EXPECT_EQ(d.holder("j", 1), nullptr);
  EXPECT_FALSE(d.has_deliverers("j"));
  EXPECT_EQ(d.holder("k", 1), C);
}

}  // namespace
}  // namespace tessera::server

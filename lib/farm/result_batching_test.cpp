// SPDX-License-Identifier: Apache-2.0
#include "result_batching.h"

#include <gtest/gtest.h>

namespace tessera::farm {
namespace {

TEST(ResultBatching, DepthIsTwoPerThreadUntilTileTimesAreKnown) {
  ResultBatching b;
  EXPECT_EQ(b.depth(1, 0.0), 2);
  EXPECT_EQ(b.depth(8, -1.0), 16);
  EXPECT_EQ(b.depth(0, 0.0), 2);  // a worker always has at least one thread
}

TEST(ResultBatching, DepthCoversWhatFinishesDuringOneLinger) {
  ResultBatching b;
  b.linger = std::chrono::milliseconds(40);
  // 10 ms tiles on 2 threads: 8 finish during 40 ms, on top of the 4 that keep the threads busy.
  EXPECT_EQ(b.depth(2, 0.010), 4 + 8);
  // Tiles slower than the linger add one per thread at most.
  EXPECT_EQ(b.depth(4, 1.0), 8 + 1);
  // Tiny tiles are capped: a worker never hoards a frame.
  EXPECT_EQ(b.depth(2, 1e-6), 4 + b.max_extra_depth);
  // No linger, no extra depth: results go as they finish.
  b.linger = std::chrono::milliseconds(0);
  EXPECT_EQ(b.depth(2, 0.010), 4);
}

TEST(ResultBatching, BytesStayWellUnderWhatTheCoordinatorReceives) {
  ResultBatching b;
  EXPECT_EQ(b.bytes_limit(0), b.max_bytes);
  EXPECT_EQ(b.bytes_limit(int64_t(64) << 20), b.max_bytes);
  EXPECT_EQ(b.bytes_limit(int64_t(4) << 20), size_t(2) << 20);
}

}  // namespace
}  // namespace tessera::farm

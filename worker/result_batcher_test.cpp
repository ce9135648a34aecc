// SPDX-License-Identifier: Apache-2.0
#include "result_batcher.h"

#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

namespace tessera::worker {
namespace {

namespace v1 = tessera::v1;

// What the batcher wrote, message by message.
struct Recorder {
  std::mutex mu;
  std::vector<v1::WorkerMessage> sent;
  ResultBatcher::Send send() {
    return [this](const v1::WorkerMessage& m) {
      std::lock_guard lock(mu);
      sent.push_back(m);
      return true;
    };
  }
  size_t size() {
    std::lock_guard lock(mu);
    return sent.size();
  }
};

v1::TileResult result(uint64_t lease, size_t pixel_bytes = 16) {
  v1::TileResult r;
  r.set_lease_id(lease);
  r.mutable_tile()->set_rgb(std::string(pixel_bytes, 'p'));
  return r;
}

farm::ResultBatching policy(int linger_ms, size_t max_tiles = 256) {
  farm::ResultBatching p;
  p.linger = std::chrono::milliseconds(linger_ms);
  p.max_tiles = max_tiles;
  return p;
}

TEST(ResultBatcher, ResultsWaitTogetherAndCarryTheirRequests) {
  Recorder rec;
  ResultBatcher b(policy(60000), 1 << 20, rec.send());  // a linger no test waits out
  b.add(result(1), 1, false);
  b.add(result(2), 3, false);
  EXPECT_EQ(rec.size(), 0u);
  b.add(result(3), 1, true);  // nothing else to render: the batch goes now
  ASSERT_EQ(rec.size(), 1u);
  const v1::TileResults& sent = rec.sent[0].results();
  ASSERT_EQ(sent.results_size(), 3);
  EXPECT_EQ(sent.results(0).lease_id(), 1u);
  EXPECT_EQ(sent.results(2).lease_id(), 3u);
  EXPECT_EQ(sent.results(1).tile().rgb(), std::string(16, 'p'));  // moved in, whole
  EXPECT_EQ(sent.request_more(), 5);
  EXPECT_EQ(b.counts().messages, 1);
  EXPECT_EQ(b.counts().results, 3);
}

TEST(ResultBatcher, AFullBatchGoesAtOnce) {
  Recorder rec;
  ResultBatcher b(policy(60000, 2), 1 << 20, rec.send());
  b.add(result(1), 1, false);
  b.add(result(2), 1, false);
  ASSERT_EQ(rec.size(), 1u);
  EXPECT_EQ(rec.sent[0].results().results_size(), 2);
}

TEST(ResultBatcher, ABatchNeverOutgrowsItsByteBound) {
  Recorder rec;
  ResultBatcher b(policy(60000), 1000, rec.send());
  b.add(result(1, 400), 1, false);
  b.add(result(2, 400), 1, false);
  b.add(result(3, 400), 1, false);  // would make ~1200 bytes: the first two go without it
  ASSERT_EQ(rec.size(), 1u);
  EXPECT_EQ(rec.sent[0].results().results_size(), 2);
  EXPECT_LE(rec.sent[0].ByteSizeLong(), 1000u);
  b.flush();
  ASSERT_EQ(rec.size(), 2u);
  EXPECT_EQ(rec.sent[1].results().results(0).lease_id(), 3u);
  b.flush();  // nothing waits: nothing is sent
  EXPECT_EQ(rec.size(), 2u);
}

TEST(ResultBatcher, NoResultWaitsLongerThanTheLinger) {
  Recorder rec;
  ResultBatcher b(policy(20), 1 << 20, rec.send());
  const auto start = std::chrono::steady_clock::now();
  b.add(result(1), 1, false);
  while (rec.size() == 0 && std::chrono::steady_clock::now() - start < std::chrono::seconds(30)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(rec.size(), 1u);  // sent by the linger thread, with nothing added after it
  EXPECT_EQ(rec.sent[0].results().results_size(), 1);
}

TEST(ResultBatcher, NoLingerSendsEachResultAlone) {
  Recorder rec;
  ResultBatcher b(policy(0), 1 << 20, rec.send());
  b.add(result(1), 1, false);
  b.add(result(2), 1, false);
  ASSERT_EQ(rec.size(), 2u);
}

TEST(ResultBatcher, LeavingSendsWhatWaits) {
  Recorder rec;
  {
    ResultBatcher b(policy(60000), 1 << 20, rec.send());
    b.add(result(7), 1, false);
  }
  ASSERT_EQ(rec.size(), 1u);
  EXPECT_EQ(rec.sent[0].results().results(0).lease_id(), 7u);
}

}  // namespace
}  // namespace tessera::worker

// SPDX-License-Identifier: Apache-2.0
#include "render_pool.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <vector>

namespace tessera::worker {
namespace {

// A one-thread pool whose thread is held by a first task until release(), so that everything
// posted after it stays queued: what remove() can withdraw is then known exactly.
class HeldPool {
 public:
  HeldPool() {
    pool.post(TaskKey{999, 0}, [this] {
      std::unique_lock lock(mu_);
      started_ = true;
      cv_.notify_all();
      cv_.wait(lock, [this] { return released_; });
    });
    std::unique_lock lock(mu_);
    cv_.wait(lock, [this] { return started_; });
  }
  ~HeldPool() { release(); }
  void release() {
    {
      std::lock_guard lock(mu_);
      released_ = true;
    }
    cv_.notify_all();
  }
  // Posts a task that records its key when it runs.
  void post(uint64_t lease, int tile) {
    pool.post(TaskKey{lease, tile}, [this, lease, tile] {
      std::lock_guard lock(mu_);
      ran_.push_back(TaskKey{lease, tile});
    });
  }
  std::vector<TaskKey> ran() {
    std::lock_guard lock(mu_);
    return ran_;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool started_ = false, released_ = false;
  std::vector<TaskKey> ran_;

 public:
  // Last: destroyed (its thread joined) before what its tasks use.
  RenderPool pool{1};
};

TEST(RenderPool, RemovingALeaseWithdrawsEveryUnstartedTileOfIt) {
  HeldPool p;
  p.post(1, 10);
  p.post(2, 20);
  p.post(1, 11);
  p.post(1, 12);
  EXPECT_EQ(p.pool.queued(), 4u);
  EXPECT_EQ(p.pool.remove(1), 3u);
  EXPECT_EQ(p.pool.queued(), 1u);
  EXPECT_EQ(p.pool.remove(1), 0u);  // nothing of it left
  EXPECT_EQ(p.pool.remove(7), 0u);  // never posted
  p.release();
  p.pool.wait_idle();
  EXPECT_EQ(p.ran(), (std::vector<TaskKey>{{2, 20}}));
}

TEST(RenderPool, RemovingATileWithdrawsOnlyThatTile) {
  HeldPool p;
  p.post(1, 10);
  p.post(1, 11);
  p.post(1, 12);
  p.post(2, 11);  // the same tile index under another lease stays
  EXPECT_TRUE(p.pool.remove(1, 11));
  EXPECT_FALSE(p.pool.remove(1, 11));  // already withdrawn
  EXPECT_FALSE(p.pool.remove(1, 13));  // not a tile of the lease
  EXPECT_FALSE(p.pool.remove(3, 11));  // not a lease here
  EXPECT_EQ(p.pool.queued(), 3u);
  p.release();
  p.pool.wait_idle();
  EXPECT_EQ(p.ran(), (std::vector<TaskKey>{{1, 10}, {1, 12}, {2, 11}}));
}

TEST(RenderPool, RemoveAllReturnsTheKeysInPostingOrder) {
  HeldPool p;
  p.post(5, 3);
  p.post(4, 0);
  p.post(5, 4);
  const std::vector<TaskKey> keys = p.pool.remove_all();
  EXPECT_EQ(keys, (std::vector<TaskKey>{{5, 3}, {4, 0}, {5, 4}}));
  EXPECT_EQ(p.pool.queued(), 0u);
  EXPECT_EQ(p.pool.busy(), 1u);  // the held task still runs
  EXPECT_TRUE(p.pool.remove_all().empty());
  p.release();
  p.pool.wait_idle();
  EXPECT_TRUE(p.ran().empty());
  EXPECT_EQ(p.pool.busy(), 0u);
}

TEST(RenderPool, ARunningTaskIsNotWithdrawn) {
  HeldPool p;  // holds lease 999, tile 0
  EXPECT_EQ(p.pool.remove(999), 0u);
  EXPECT_FALSE(p.pool.remove(999, 0));
  EXPECT_EQ(p.pool.busy(), 1u);
  p.release();
  p.pool.wait_idle();
  EXPECT_EQ(p.pool.busy(), 0u);
}

}  // namespace
}  // namespace tessera::worker

// SPDX-License-Identifier: Apache-2.0
// Span leases (docs/farm.md, "Lease rules"): a lease of several consecutive tiles of a frame, whose
// tiles each finish, go back or lose a race on their own. Deterministic time, no network.
#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

#include "scheduler.h"

namespace tessera::server {
namespace {

using namespace std::chrono_literals;

struct SpanRecorder : SchedulerListener {
  std::vector<std::pair<Lease, LeaseEnd>> ended;
  std::vector<std::pair<LeaseId, int>> lost;
  std::vector<TileKey> finished;
  void lease_ended(const Lease& l, LeaseEnd e) override { ended.emplace_back(l, e); }
  void span_tile_lost(const Lease& l, int tile) override { lost.emplace_back(l.id, tile); }
  void tile_finished(const TileKey& k, const TileOutput&, WorkerId) override { finished.push_back(k); }
};

class SchedulerSpansTest : public ::testing::Test {
 protected:
  TimePoint now{};
  SchedulerOptions opts() {
    SchedulerOptions o;
    o.lease_timeout = 10s;
    o.initial_leases_per_thread = 0;  // no slow start: these tests look at span sizes
    o.factoring = 0;
    return o;
  }
  std::unique_ptr<Scheduler> s = make(opts());
  SpanRecorder rec;

  std::unique_ptr<Scheduler> make(SchedulerOptions o) {
    auto sc = std::make_unique<Scheduler>(o, [this] { return now; });
    sc->set_listener(&rec);
    return sc;
  }
  static JobSpec spec(int w, int h, int tile, int frames = 1) {
    JobSpec j;
    j.bundle_sha256 = "abc";
    j.width = w;
    j.height = h;
    j.tile_size = tile;
    j.last_frame = frames - 1;
    return j;
  }
  WorkerId spans_worker(const std::string& name, int threads = 1) {
    return s->add_worker({name, "", threads, "AVX2", true});
  }
  static TileOutput out(double seconds = 0.01) { return {std::make_shared<const std::string>("px"), 10, seconds}; }
  std::vector<Assignment> pull(WorkerId w, int n) {
    s->request_tiles(w, n);
    return s->dispatch();
  }
  // The worker has shown its rate: one tile of `seconds` done.
  void warm_up(WorkerId w, double seconds) {
    auto a = pull(w, 1);
    ASSERT_EQ(a.size(), 1u);
    ASSERT_EQ(a[0].lease.count, 1);  // no rate yet: one tile
    ASSERT_EQ(s->complete(w, a[0].lease.id, a[0].lease.tile.tile, out(seconds)), Scheduler::ResultOutcome::kAccepted);
  }
};

TEST_F(SchedulerSpansTest, AWorkerThatShowedItsRateGetsOneLeaseForManyTilesUpToItsSpanTime) {
  const JobId id = s->submit(spec(32 * 40, 32 * 10, 32));  // 400 tiles
  const WorkerId w = spans_worker("a", 2);
  warm_up(w, 0.01);  // 10 ms a tile on one thread: 100 ms over two threads is 20 tiles
  auto as = pull(w, 50);
  ASSERT_FALSE(as.empty());
  EXPECT_EQ(as[0].lease.count, 20);
  EXPECT_EQ(as[0].lease.tile.tile, 1);
  EXPECT_EQ(as[0].grid.count(), 400);
  // The rest of what it asked for in further spans, consecutive, within the frame.
  int tiles = 0, next = 1;
  for (const auto& a : as) {
    EXPECT_EQ(a.lease.tile.tile, next);
    next += a.lease.count;
    tiles += a.lease.count;
  }
  EXPECT_EQ(tiles, 50);
  EXPECT_EQ(s->worker(w)->in_flight, 50);
  EXPECT_EQ(s->worker(w)->leases, int(as.size()));
  EXPECT_EQ(s->job(id)->tiles_leased, 50);
}

TEST_F(SchedulerSpansTest, SpansStayWithinAFrameAndAWorkerWithoutSpansGetsSingleTiles) {
  s->submit(spec(64, 64, 32, 3));  // 4 tiles a frame
  const WorkerId old = s->add_worker({"old", "", 1, "AVX2", false});
  const WorkerId w = spans_worker("new");
  warm_up(w, 0.001);
  auto as = pull(w, 8);
  ASSERT_EQ(as.size(), 3u);  // tiles 1-3 of frame 0, frame 1 whole, one tile of frame 2
  EXPECT_EQ(as[0].lease.count, 3);
  EXPECT_EQ(as[1].lease.count, 4);
  EXPECT_EQ(as[1].lease.tile.frame, 1);
  EXPECT_EQ(as[2].lease.count, 1);
  for (const auto& a : pull(old, 3)) EXPECT_EQ(a.lease.count, 1);
}

TEST_F(SchedulerSpansTest, EachTileOfASpanFinishesOnItsOwnAndTheLeaseEndsWithItsLast) {
  const JobId id = s->submit(spec(32 * 8, 32, 32));  // 8 tiles
  const WorkerId w = spans_worker("a");
  warm_up(w, 0.001);
  auto as = pull(w, 7);
  ASSERT_EQ(as.size(), 1u);
  const Lease l = as[0].lease;
  ASSERT_EQ(l.count, 7);
  // Out of order, as render threads finish them.
  for (int t : {3, 1, 7, 2, 6, 5}) {
    EXPECT_EQ(s->complete(w, l.id, t, out()), Scheduler::ResultOutcome::kAccepted);
    EXPECT_TRUE(s->lease(l.id));
  }
  // A second result for a tile already in: nothing counts twice.
  EXPECT_EQ(s->complete(w, l.id, 3, out()), Scheduler::ResultOutcome::kStaleLease);
  EXPECT_EQ(s->lease(l.id)->pending_tiles(), 1);
  EXPECT_EQ(s->worker(w)->in_flight, 1);
  EXPECT_EQ(s->complete(w, l.id, 4, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_FALSE(s->lease(l.id));
  ASSERT_FALSE(rec.ended.empty());
  EXPECT_EQ(rec.ended.back().second, LeaseEnd::kCompleted);
  EXPECT_EQ(s->job(id)->state, JobState::kDone);
  EXPECT_EQ(rec.finished.size(), 8u);
  EXPECT_EQ(s->worker(w)->tiles_done, 8);
}

TEST_F(SchedulerSpansTest, AWorkerThatLeavesMidSpanLosesOnlyItsUnfinishedTilesWhichGoOutAgainInOrder) {
  s->submit(spec(32 * 10, 32, 32));  // 10 tiles
  const WorkerId a = spans_worker("a");
  warm_up(a, 0.001);
  auto as = pull(a, 6);
  ASSERT_EQ(as.size(), 1u);
  const Lease l = as[0].lease;  // tiles 1-6
  ASSERT_EQ(s->complete(a, l.id, 1, out()), Scheduler::ResultOutcome::kAccepted);
  ASSERT_EQ(s->complete(a, l.id, 4, out()), Scheduler::ResultOutcome::kAccepted);
  s->remove_worker(a, "killed");
  EXPECT_EQ(rec.ended.back().first.pending_tiles(), 0);
  const WorkerId b = spans_worker("b");
  warm_up(b, 0.001);  // takes tile 2: the first requeued
  auto again = pull(b, 20);
  std::vector<int> tiles;
  for (const auto& x : again) {
    for (int t = x.lease.tile.tile; t < x.lease.tile.tile + x.lease.count; ++t) tiles.push_back(t);
  }
  // 3 (requeued, alone: 4 is done), 5-6 (requeued, one span), then the fresh 7-9.
  EXPECT_EQ(tiles, (std::vector<int>{3, 5, 6, 7, 8, 9}));
  ASSERT_GE(again.size(), 2u);
  EXPECT_EQ(again[0].lease.count, 1);
  EXPECT_EQ(again[1].lease.count, 2);
}

TEST_F(SchedulerSpansTest, TilesGivenBackSingly_TheRestOfTheSpanStaysWithItsWorker) {
  s->submit(spec(32 * 6, 32, 32));
  const WorkerId a = spans_worker("a");
  warm_up(a, 0.001);
  const Lease l = pull(a, 5)[0].lease;  // tiles 1-5
  ASSERT_EQ(l.count, 5);
  s->return_tiles(a, {{l.id, 4}, {l.id, 5}, {l.id + 99, 1}});  // the last is no lease: ignored
  ASSERT_TRUE(s->lease(l.id));
  EXPECT_EQ(s->lease(l.id)->pending_tiles(), 3);
  EXPECT_EQ(s->complete(a, l.id, 5, out()), Scheduler::ResultOutcome::kStaleLease);  // given back
  const WorkerId b = spans_worker("b");
  auto got = pull(b, 2);
  ASSERT_EQ(got.size(), 2u);  // b has no rate yet: single tiles, in tile order
  EXPECT_EQ(got[0].lease.tile.tile, 4);
  EXPECT_EQ(got[1].lease.tile.tile, 5);
  EXPECT_FALSE(got[1].lease.speculative);
  for (int t : {1, 2, 3}) EXPECT_EQ(s->complete(a, l.id, t, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_FALSE(s->lease(l.id));
  EXPECT_EQ(rec.ended.back().second, LeaseEnd::kCompleted);
}

TEST_F(SchedulerSpansTest, ASpeculativeCopyTakesTheLastTileOfASlowSpanAndWinningItTakesItOutOfTheSpan) {
  const JobId id = s->submit(spec(32 * 5, 32, 32));
  const WorkerId slow = spans_worker("slow");
  warm_up(slow, 0.001);
  const Lease l = pull(slow, 4)[0].lease;  // tiles 1-4: nothing is queued any more
  ASSERT_EQ(l.count, 4);
  const WorkerId fast = spans_worker("fast");
  auto copy = pull(fast, 1);
  ASSERT_EQ(copy.size(), 1u);
  EXPECT_TRUE(copy[0].lease.speculative);
  EXPECT_EQ(copy[0].lease.tile.tile, 4);
  EXPECT_EQ(copy[0].lease.count, 1);
  auto copy2 = pull(fast, 1);  // the next copy: tile 3, the last with a single copy
  ASSERT_EQ(copy2.size(), 1u);
  EXPECT_EQ(copy2[0].lease.tile.tile, 3);
  ASSERT_EQ(s->complete(fast, copy[0].lease.id, 4, out()), Scheduler::ResultOutcome::kAccepted);
  ASSERT_EQ(rec.lost.size(), 1u);
  EXPECT_EQ(rec.lost[0], (std::pair<LeaseId, int>{l.id, 4}));
  EXPECT_EQ(s->lease(l.id)->pending_tiles(), 3);
  // The slow worker's late result for it is ignored; its own tiles still count.
  EXPECT_EQ(s->complete(slow, l.id, 4, out()), Scheduler::ResultOutcome::kStaleLease);
  EXPECT_EQ(s->complete(slow, l.id, 3, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_FALSE(s->lease(copy2[0].lease.id));  // the copy of 3 lost the race: revoked
  EXPECT_EQ(rec.ended.back().second, LeaseEnd::kLostRace);
  for (int t : {1, 2}) EXPECT_EQ(s->complete(slow, l.id, t, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_FALSE(s->lease(l.id));
  EXPECT_EQ(s->job(id)->state, JobState::kDone);
  EXPECT_EQ(rec.finished.size(), 5u);
}

TEST_F(SchedulerSpansTest, FactoringShrinksSpansAsTheQueueRunsOut) {
  SchedulerOptions o = opts();
  o.factoring = 2;
  s = make(o);
  s->submit(spec(32 * 100, 32, 32));  // 100 tiles
  const WorkerId w = spans_worker("a");
  const WorkerId v = spans_worker("b");
  warm_up(w, 1e-6);  // so fast that its span time allows the most
  warm_up(v, 1e-6);
  std::vector<int> sizes;
  for (int round = 0; round < 200 && s->queued_tiles() > 0; ++round) {
    for (WorkerId x : {w, v}) {
      for (const auto& a : pull(x, 64)) {
        if (a.lease.speculative) continue;  // a copy of a tile finished below: it loses the race
        sizes.push_back(a.lease.count);
        for (int t = a.lease.tile.tile; t < a.lease.tile.tile + a.lease.count; ++t) {
          ASSERT_EQ(s->complete(a.lease.worker, a.lease.id, t, out(1e-6)), Scheduler::ResultOutcome::kAccepted);
        }
      }
    }
  }
  ASSERT_GE(sizes.size(), 8u);
  // 98 queued over 2 threads and factoring 2: a first span of 24 (then the one tile left of that
  // worker's share of 25); each later dispatch's spans are a thread's share of what is left.
  EXPECT_EQ(sizes[0], 24);
  EXPECT_EQ(sizes[1], 1);
  EXPECT_EQ(sizes.back(), 1);
  const size_t tail = sizes.size() - sizes.size() / 3;
  for (size_t i = tail; i < sizes.size(); ++i) EXPECT_LE(sizes[i], 4) << i;
}

TEST_F(SchedulerSpansTest, MaxSpanTilesOneGivesSingleTileLeases) {
  SchedulerOptions o = opts();
  o.max_span_tiles = 1;
  s = make(o);
  s->submit(spec(32 * 10, 32, 32));
  const WorkerId w = spans_worker("a");
  warm_up(w, 0.001);
  auto as = pull(w, 5);
  ASSERT_EQ(as.size(), 5u);
  for (const auto& a : as) EXPECT_EQ(a.lease.count, 1);
}

// Random actions on span leases: every tile's result is accepted exactly once, what workers
// hold always equals the pending tiles of their leases, and the job ends done.
TEST_F(SchedulerSpansTest, RandomSpansWorkersAndFailuresNeverLoseOrDoubleATile) {
  for (int seed = 0; seed < 20; ++seed) {
    SchedulerOptions o = opts();
    o.factoring = 2;
    o.initial_leases_per_thread = 2;
    s = make(o);
    rec = {};
    const JobId id = s->submit(spec(32 * 16, 32 * 4, 32, 3));  // 192 tiles
    std::mt19937 rng{unsigned(seed)};
    std::vector<WorkerId> ws;
    std::map<LeaseId, Assignment> held;
    std::set<std::pair<int, int>> accepted;
    for (int step = 0; step < 20000 && s->job(id)->state != JobState::kDone; ++step) {
      const int action = int(rng() % 20);
      if (ws.empty() || action == 0) {
        ws.push_back(spans_worker("w" + std::to_string(ws.size()), 1 + int(rng() % 3)));
      } else if (action == 1 && ws.size() > 1) {
        const size_t k = rng() % ws.size();
        s->remove_worker(ws[k], "gone");
        ws.erase(ws.begin() + long(k));
      } else if (action <= 5) {
        for (auto& a : pull(ws[rng() % ws.size()], 1 + int(rng() % 20))) held[a.lease.id] = a;
      } else if (action == 6 && !held.empty()) {
        auto it = std::next(held.begin(), long(rng() % held.size()));
        const Assignment& a = it->second;
        const int t = a.lease.tile.tile + int(rng() % unsigned(a.lease.count));
        s->return_tiles(a.lease.worker, {{a.lease.id, t}});
      } else if (!held.empty()) {
        auto it = std::next(held.begin(), long(rng() % held.size()));
        const Assignment& a = it->second;
        const int t = a.lease.tile.tile + int(rng() % unsigned(a.lease.count));
        if (s->complete(a.lease.worker, a.lease.id, t, out()) == Scheduler::ResultOutcome::kAccepted) {
          EXPECT_TRUE(accepted.insert({a.lease.tile.frame, t}).second) << "tile accepted twice";
        }
        if (!s->lease(a.lease.id)) held.erase(it);
      }
      int64_t pending = 0;
      for (const auto& [lid, a] : held) {
        if (auto l = s->lease(lid)) pending += l->pending_tiles();
      }
      int64_t in_flight = 0;
      for (const auto& w : s->workers()) in_flight += w.in_flight;
      ASSERT_EQ(in_flight, pending) << "seed " << seed << " step " << step;
    }
    EXPECT_EQ(s->job(id)->state, JobState::kDone) << "seed " << seed;
    EXPECT_EQ(accepted.size(), 192u) << "seed " << seed;
    EXPECT_EQ(rec.finished.size(), 192u) << "seed " << seed;
  }
}

}  // namespace
}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// Scheduler unit tests: deterministic time through an injected clock, no network.
#include "scheduler.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

namespace tessera::server {
namespace {

using namespace std::chrono_literals;

struct Recorder : SchedulerListener {
  std::vector<std::string> log;
  std::vector<std::pair<Lease, LeaseEnd>> ended;
  std::vector<TileKey> finished;
  std::vector<int> frames;
  void job_state_changed(const JobId& id, JobState s) override { log.push_back(id + ":" + job_state_name(s)); }
  void lease_ended(const Lease& l, LeaseEnd e) override { ended.emplace_back(l, e); }
  void tile_finished(const TileKey& k, const TileOutput&, WorkerId) override { finished.push_back(k); }
  void frame_finished(const JobId&, int frame) override { frames.push_back(frame); }
};

class SchedulerTest : public ::testing::Test {
 protected:
  TimePoint now{};
  int next_id = 0;
  SchedulerOptions opts() {
    SchedulerOptions o;
    o.lease_timeout = 10s;
    o.initial_leases_per_thread = 0;  // unbounded; LeaseCredit* tests turn it on
    o.factoring = 0;                  // no share either; Factoring* tests turn it on
    return o;
  }
  Scheduler s{opts(), [this] { return now; }, [this] { return "job" + std::to_string(++next_id); }};
  Recorder rec;
  void SetUp() override { s.set_listener(&rec); }

  JobSpec spec(int w, int h, int tile, int frames = 1, int priority = 0) {
    JobSpec j;
    j.name = "test";
    j.bundle_sha256 = "abc";
    j.width = w;
    j.height = h;
    j.tile_size = tile;
    j.first_frame = 0;
    j.last_frame = frames - 1;
    j.priority = priority;
    return j;
  }
  WorkerId worker(const std::string& name) { return s.add_worker({name, "", 1, "AVX2"}); }
  static TileOutput out(uint64_t rays = 10) {
    return {std::make_shared<const std::string>("pixels"), rays, 0.5};
  }
  std::vector<Assignment> pull(WorkerId w, int n) {
    s.request_tiles(w, n);
    return s.dispatch();
  }
};

TEST_F(SchedulerTest, SplitsFramesIntoTilesWithEdgeTiles) {
  const JobId id = s.submit(spec(40, 20, 16, 2));
  auto j = s.job(id);
  ASSERT_TRUE(j);
  EXPECT_EQ(j->tiles_per_frame, 3 * 2);
  EXPECT_EQ(j->tiles_total, 12);
  EXPECT_EQ(j->state, JobState::kQueued);
  EXPECT_EQ(*s.tile_rect(id, 0, 2), (TileRect{32, 0, 8, 16}));
  EXPECT_EQ(*s.tile_rect(id, 1, 5), (TileRect{32, 16, 8, 4}));
  EXPECT_FALSE(s.tile_rect(id, 2, 0));
}

TEST_F(SchedulerTest, PullAssignsInOrderAndCompletesJob) {
  const JobId id = s.submit(spec(32, 16, 16, 2));
  const WorkerId w = worker("a");
  auto as = pull(w, 10);
  ASSERT_EQ(as.size(), 4u);
  EXPECT_EQ(as[0].lease.tile.frame, 0);
  EXPECT_EQ(as[0].lease.tile.tile, 0);
  EXPECT_EQ(as[3].lease.tile.frame, 1);
  EXPECT_EQ(s.job(id)->state, JobState::kRunning);
  for (const auto& a : as) EXPECT_EQ(s.complete(w, a.lease.id, a.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  auto j = s.job(id);
  EXPECT_EQ(j->state, JobState::kDone);
  EXPECT_EQ(j->tiles_done, 4);
  EXPECT_EQ(j->rays, 40u);
  EXPECT_EQ(rec.frames, (std::vector<int>{0, 1}));
  EXPECT_EQ(s.worker(w)->tiles_done, 4);
  // The standing request for 6 more tiles is still there but there is nothing to do.
  EXPECT_TRUE(s.dispatch().empty());
}

TEST_F(SchedulerTest, FastWorkersGetMoreBecauseTheyPull) {
  s.submit(spec(64, 64, 16));  // 16 tiles
  const WorkerId fast = worker("fast"), slow = worker("slow");
  s.request_tiles(slow, 1);
  auto slow_tiles = s.dispatch();
  ASSERT_EQ(slow_tiles.size(), 1u);
  int fast_done = 0;
  while (true) {
    auto a = pull(fast, 1);
    if (a.empty() || a[0].lease.speculative) break;
    s.complete(fast, a[0].lease.id, a[0].lease.tile.tile, out());
    ++fast_done;
  }
  EXPECT_EQ(fast_done, 15);
}

TEST_F(SchedulerTest, HigherPriorityFirstThenSubmitOrder) {
  const JobId low = s.submit(spec(16, 16, 16, 1, 0));
  const JobId low2 = s.submit(spec(16, 16, 16, 1, 0));
  const JobId high = s.submit(spec(16, 16, 16, 1, 5));
  const WorkerId w = worker("a");
  auto as = pull(w, 3);
  ASSERT_EQ(as.size(), 3u);
  EXPECT_EQ(as[0].lease.tile.job, high);
  EXPECT_EQ(as[1].lease.tile.job, low);
  EXPECT_EQ(as[2].lease.tile.job, low2);
}

TEST_F(SchedulerTest, WorkerLeavingRequeuesItsTilesAtTheFront) {
  const JobId id = s.submit(spec(48, 16, 16));  // 3 tiles
  const WorkerId a = worker("a");
  auto got = pull(a, 2);
  ASSERT_EQ(got.size(), 2u);
  s.remove_worker(a, "disconnected");
  EXPECT_EQ(s.queued_tiles(), 3u);
  const WorkerId b = worker("b");
  auto again = pull(b, 3);
  ASSERT_EQ(again.size(), 3u);
  std::set<int> tiles;
  for (auto& x : again) tiles.insert(x.lease.tile.tile);
  EXPECT_EQ(tiles, (std::set<int>{0, 1, 2}));
  // A late result of the dead worker's lease is ignored.
  EXPECT_EQ(s.complete(a, got[0].lease.id, got[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kStaleLease);
  for (auto& x : again) s.complete(b, x.lease.id, x.lease.tile.tile, out());
  EXPECT_EQ(s.job(id)->state, JobState::kDone);
  EXPECT_EQ(s.job(id)->tiles_done, 3);
}

TEST_F(SchedulerTest, MissedHeartbeatsExpireTheWorker) {
  s.submit(spec(16, 16, 16));
  const WorkerId a = worker("a"), b = worker("b");
  auto got = pull(a, 1);
  ASSERT_EQ(got.size(), 1u);
  now += 6s;
  s.heartbeat(a);
  s.heartbeat(b);
  now += 6s;  // a renewed at 6 s: alive until 16 s
  EXPECT_TRUE(s.expire().empty());
  now += 5s;
  s.heartbeat(b);
  auto dropped = s.expire();
  EXPECT_EQ(dropped, (std::vector<WorkerId>{a}));
  EXPECT_FALSE(s.worker(a));
  ASSERT_EQ(rec.ended.size(), 1u);
  EXPECT_EQ(rec.ended[0].second, LeaseEnd::kExpired) << "what tessera_lease_expiries_total counts";
  auto re = pull(b, 1);
  ASSERT_EQ(re.size(), 1u);
  EXPECT_EQ(re[0].lease.tile.tile, 0);
  EXPECT_FALSE(re[0].lease.speculative);
}

// Factoring: each dispatch gives a worker at most its share of the queue, ceil(queued / (2 x
// threads of the farm)) leases a thread but never fewer than two, so a worker that asks for
// much early takes a large share and the last tiles are spread over every worker.
TEST_F(SchedulerTest, FactoringGivesEachWorkerItsShareOfWhatIsQueued) {
  SchedulerOptions o = opts();
  o.factoring = 2;
  o.speculate = false;
  Scheduler sc{o, [this] { return now; }, [this] { return "job" + std::to_string(++next_id); }};
  sc.submit(spec(64, 64, 8));  // 64 tiles
  const WorkerId a = sc.add_worker({"a", "", 2, "AVX2"});
  const WorkerId b = sc.add_worker({"b", "", 2, "AVX2"});
  const auto pull_from = [&](WorkerId w, int n) {
    sc.request_tiles(w, n);
    std::vector<Assignment> mine;
    for (auto& x : sc.dispatch()) {
      if (x.lease.worker == w) mine.push_back(x);
    }
    return mine;
  };
  auto got_a = pull_from(a, 100);
  EXPECT_EQ(got_a.size(), 16u) << "64 queued / (2 x 4 threads) = 8 a thread, 2 threads";
  EXPECT_EQ(sc.queued_tiles(), 48u);
  auto got_b = pull_from(b, 100);
  EXPECT_EQ(got_b.size(), 12u) << "48 / 8 = 6 a thread";
  // a renders its 16: its next share is 36 / 8, rounded up, = 5 a thread.
  for (const auto& x : got_a) ASSERT_EQ(sc.complete(a, x.lease.id, x.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  got_a = sc.dispatch();
  EXPECT_EQ(got_a.size(), 10u);
  // Near the end the share is the floor, two a thread: what is left goes to b too.
  for (const auto& x : got_a) sc.complete(a, x.lease.id, x.lease.tile.tile, out());
  for (const auto& x : got_b) sc.complete(b, x.lease.id, x.lease.tile.tile, out());
  EXPECT_EQ(sc.queued_tiles(), 26u);
  int rounds = 0;
  while (sc.queued_tiles() > 0 && rounds++ < 20) {
    auto as = sc.dispatch();
    int held_a = 0, held_b = 0;
    for (const auto& x : as) (x.lease.worker == a ? held_a : held_b)++;
    const int floor_or_share = std::max(2, int((sc.queued_tiles() + as.size() + 7) / 8)) * 2;
    EXPECT_LE(held_a, floor_or_share);
    EXPECT_LE(held_b, floor_or_share);
    EXPECT_GT(held_b, 0) << "b gets its share of every round";
    for (const auto& x : as) sc.complete(x.lease.worker, x.lease.id, x.lease.tile.tile, out());
  }
  EXPECT_EQ(sc.queued_tiles(), 0u);
}

TEST_F(SchedulerTest, IdleWorkerDuplicatesOldestInFlightTileFirstCopyWins) {
  const JobId id = s.submit(spec(32, 16, 16));  // 2 tiles
  const WorkerId a = worker("a"), b = worker("b");
  auto ta = pull(a, 2);
  ASSERT_EQ(ta.size(), 2u);
  auto tb = pull(b, 1);
  ASSERT_EQ(tb.size(), 1u);
  EXPECT_TRUE(tb[0].lease.speculative);
  EXPECT_EQ(tb[0].lease.tile.tile, 0);  // the oldest
  // Never a third copy, never a copy of its own tile.
  EXPECT_EQ(pull(b, 1).size(), 1u);  // tile 1's copy
  EXPECT_TRUE(pull(b, 1).empty());
  EXPECT_TRUE(pull(a, 1).empty());
  // b finishes tile 0 first: a's copy is revoked, its late result is stale.
  EXPECT_EQ(s.complete(b, tb[0].lease.id, tb[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  bool revoked = false;
  for (auto& [l, why] : rec.ended) revoked |= l.id == ta[0].lease.id && why == LeaseEnd::kLostRace;
  EXPECT_TRUE(revoked);
  EXPECT_EQ(s.complete(a, ta[0].lease.id, ta[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kStaleLease);
  EXPECT_EQ(s.job(id)->tiles_done, 1);
  EXPECT_EQ(rec.finished.size(), 1u);
}

TEST_F(SchedulerTest, NoSpeculationWhenDisabled) {
  SchedulerOptions o = opts();
  o.speculate = false;
  Scheduler t(o, [this] { return now; });
  t.submit(spec(16, 16, 16));
  const WorkerId a = t.add_worker({"a", "", 1, ""}), b = t.add_worker({"b", "", 1, ""});
  t.request_tiles(a, 1);
  EXPECT_EQ(t.dispatch().size(), 1u);
  t.request_tiles(b, 1);
  EXPECT_TRUE(t.dispatch().empty());
}

TEST_F(SchedulerTest, CancelStopsHandingOutAndRevokesLeases) {
  const JobId id = s.submit(spec(64, 16, 16));
  const WorkerId a = worker("a");
  auto got = pull(a, 2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(s.cancel(id), Scheduler::CancelResult::kCancelled);
  EXPECT_EQ(s.job(id)->state, JobState::kCancelled);
  EXPECT_TRUE(pull(a, 4).empty());
  EXPECT_EQ(s.complete(a, got[0].lease.id, got[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kStaleLease);
  int cancelled = 0;
  for (auto& [l, why] : rec.ended) cancelled += why == LeaseEnd::kCancelled;
  EXPECT_EQ(cancelled, 2);
  EXPECT_EQ(s.cancel(id), Scheduler::CancelResult::kAlreadyEnded);
  EXPECT_EQ(s.cancel("nope"), Scheduler::CancelResult::kUnknownJob);
}

TEST_F(SchedulerTest, FinishedTilesKeptUntilFrameAcknowledged) {
  const JobId id = s.submit(spec(32, 16, 16, 2));
  const WorkerId a = worker("a");
  auto got = pull(a, 3);
  for (auto& x : got) s.complete(a, x.lease.id, x.lease.tile.tile, out());
  EXPECT_EQ(s.finished_tiles(id).size(), 3u);
  EXPECT_EQ(s.acknowledge_frame(id, 1), Scheduler::AckResult::kNotFinished);
  EXPECT_EQ(s.acknowledge_frame(id, 0), Scheduler::AckResult::kAcknowledged);
  EXPECT_EQ(s.acknowledge_frame(id, 0), Scheduler::AckResult::kAcknowledged);  // idempotent
  EXPECT_EQ(s.acknowledge_frame(id, 7), Scheduler::AckResult::kUnknownFrame);
  EXPECT_EQ(s.acknowledge_frame("x", 0), Scheduler::AckResult::kUnknownJob);
  auto left = s.finished_tiles(id);
  ASSERT_EQ(left.size(), 1u);
  EXPECT_EQ(left[0].first.frame, 1);
  EXPECT_EQ(s.job(id)->frames_acknowledged, (std::vector<int>{0}));
}

TEST_F(SchedulerTest, ReturnedLeasesAreRequeued) {
  s.submit(spec(32, 16, 16));
  const WorkerId a = worker("a");
  auto got = pull(a, 2);
  s.return_leases(a, {got[1].lease.id});
  EXPECT_EQ(s.queued_tiles(), 1u);
  EXPECT_EQ(s.worker(a)->in_flight, 1);
}

TEST_F(SchedulerTest, ForeignLeaseIsStale) {
  s.submit(spec(16, 16, 16));
  const WorkerId a = worker("a"), b = worker("b");
  auto got = pull(a, 1);
  EXPECT_EQ(s.complete(b, got[0].lease.id, got[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kStaleLease);
  EXPECT_EQ(s.complete(a, got[0].lease.id, got[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
}

TEST_F(SchedulerTest, FrameRangeUsesAbsoluteFrameNumbers) {
  JobSpec j = spec(16, 16, 16);
  j.first_frame = 5;
  j.last_frame = 6;
  const JobId id = s.submit(j);
  const WorkerId a = worker("a");
  auto got = pull(a, 2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].lease.tile.frame, 5);
  EXPECT_EQ(got[1].lease.tile.frame, 6);
  for (auto& x : got) s.complete(a, x.lease.id, x.lease.tile.tile, out());
  EXPECT_EQ(s.job(id)->frames_done, (std::vector<int>{5, 6}));
}

TEST_F(SchedulerTest, FaultsRequeueTheTileAndBlocklistAfterMaxFaults) {
  const JobId id = s.submit(spec(64, 16, 16));  // 4 tiles
  const WorkerId bad = worker("bad"), good = worker("good");
  for (int k = 1; k <= 3; ++k) {
    auto got = pull(bad, 1);
    ASSERT_EQ(got.size(), 1u) << "fault " << k;
    EXPECT_EQ(s.fault(bad, id, got[0].lease.id, "NaN"), k);
    EXPECT_FALSE(s.lease(got[0].lease.id));  // ended, tile back in the queue
    EXPECT_EQ(s.queued_tiles(), 4u);
  }
  EXPECT_EQ(s.job(id)->blocklisted, std::vector<std::string>{"bad"});
  EXPECT_TRUE(pull(bad, 1).empty());  // nothing for it, not even a speculative copy
  EXPECT_EQ(pull(good, 4).size(), 4u);
  EXPECT_EQ(s.job(id)->state, JobState::kRunning);
}

TEST_F(SchedulerTest, BlocklistedWorkerStillGetsOtherJobs) {
  const JobId first = s.submit(spec(16, 16, 16, 1, 10));
  const JobId second = s.submit(spec(16, 16, 16, 1, 0));
  const WorkerId bad = worker("bad");
  worker("idle");  // keeps the first job from failing
  for (int k = 0; k < 3; ++k) s.fault(bad, first, pull(bad, 1).at(0).lease.id, "wrong size");
  auto got = pull(bad, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].lease.tile.job, second);
}

TEST_F(SchedulerTest, JobFailsWhenEveryWorkerIsBlocklisted) {
  const JobId id = s.submit(spec(32, 16, 16));
  const WorkerId a = worker("a"), b = worker("b");
  for (WorkerId w : {a, b}) {
    for (int k = 0; k < 3; ++k) s.fault(w, id, pull(w, 1).at(0).lease.id, "cannot load scene");
  }
  auto snap = s.job(id);
  EXPECT_EQ(snap->state, JobState::kFailed);
  EXPECT_NE(snap->error.find("every connected worker (2) is blocklisted"), std::string::npos) << snap->error;
  EXPECT_NE(snap->error.find("cannot load scene"), std::string::npos) << snap->error;
  EXPECT_EQ(s.queued_tiles(), 0u);
  EXPECT_EQ(rec.log.back(), id + ":failed");
}

TEST_F(SchedulerTest, BlocklistIsByNameSoReconnectingDoesNotReset) {
  const JobId id = s.submit(spec(32, 16, 16));
  worker("other");
  WorkerId bad = worker("bad");
  for (int k = 0; k < 3; ++k) {
    s.fault(bad, id, pull(bad, 1).at(0).lease.id, "NaN");
    s.remove_worker(bad, "reconnect");
    bad = worker("bad");
  }
  EXPECT_TRUE(pull(bad, 1).empty());
}

TEST_F(SchedulerTest, RestoreKeepsDoneTilesAndQueuesTheRest) {
  JobRecord r;
  r.id = "old";
  r.spec = spec(32, 16, 16, 2);  // 2 tiles a frame, frames 0-1
  r.state = JobState::kRunning;
  r.seq = 7;
  r.done.push_back({0, 0, out(5)});
  r.done.push_back({0, 1, out(5)});
  r.done.push_back({1, 1, out(5)});
  r.acknowledged = {0};
  s.restore(r);
  s.set_next_lease(100);
  auto snap = s.job("old");
  ASSERT_TRUE(snap);
  EXPECT_EQ(snap->tiles_done, 3);
  EXPECT_EQ(snap->frames_acknowledged, std::vector<int>{0});
  EXPECT_EQ(s.finished_tiles("old").size(), 1u);  // frame 1 tile 1; frame 0 was delivered
  EXPECT_EQ(s.tiles_held(), 2) << "only frame 1 is in memory: frame 0 was delivered";
  auto got = pull(worker("a"), 5);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].lease.tile.frame, 1);
  EXPECT_EQ(got[0].lease.tile.tile, 0);
  EXPECT_EQ(got[0].lease.id, 100u);  // lease ids continue after the stored high-water mark
  // New jobs come after restored ones.
  const JobId fresh = s.submit(spec(16, 16, 16));
  EXPECT_GT(s.job(fresh)->seq, 7u);
}

TEST_F(SchedulerTest, RestoredJobWithEveryTileDoneIsDone) {
  JobRecord r;
  r.id = "old";
  r.spec = spec(16, 16, 16);
  r.state = JobState::kRunning;  // the crash came before the state change was written
  r.done.push_back({0, 0, out()});
  s.restore(r);
  EXPECT_EQ(s.job("old")->state, JobState::kDone);
  EXPECT_EQ(s.queued_tiles(), 0u);
}

TEST_F(SchedulerTest, RestoredDoneJobWithALostTileRunsAgain) {
  // Stored as done, but the store dropped one tile whose record was unreadable: the job must
  // run again for that tile rather than stay done one tile short.
  JobRecord r;
  r.id = "old";
  r.spec = spec(32, 16, 16);  // 2 tiles
  r.state = JobState::kDone;
  r.ended = Clock::now();
  r.done.push_back({0, 1, out()});
  s.restore(r);
  EXPECT_EQ(s.job("old")->state, JobState::kRunning);
  EXPECT_FALSE(s.job("old")->ended);
  const WorkerId a = worker("a");
  auto got = pull(a, 2);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].lease.tile.tile, 0);
  EXPECT_EQ(s.complete(a, got[0].lease.id, got[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_EQ(s.job("old")->state, JobState::kDone);
}

TEST_F(SchedulerTest, ForgetDropsOnlyEndedJobs) {
  const JobId id = s.submit(spec(16, 16, 16));
  EXPECT_FALSE(s.forget(id));  // still queued
  const WorkerId a = worker("a");
  auto got = pull(a, 1);
  s.complete(a, got[0].lease.id, got[0].lease.tile.tile, out());
  EXPECT_FALSE(s.all_acknowledged(id));
  EXPECT_EQ(s.acknowledge_frame(id, 0), Scheduler::AckResult::kAcknowledged);
  EXPECT_TRUE(s.all_acknowledged(id));
  EXPECT_TRUE(s.forget(id));
  EXPECT_FALSE(s.job(id));
  EXPECT_TRUE(s.jobs().empty());
}

TEST_F(SchedulerTest, HeldJobGetsNoLeasesButItsResultsCountAndOtherJobsRun) {
  const JobId slow = s.submit(spec(64, 16, 16, 1, 5));  // 4 tiles, first in line
  const JobId other = s.submit(spec(32, 16, 16));       // 2 tiles
  const WorkerId a = worker("a"), b = worker("b");
  auto ta = pull(a, 1);
  ASSERT_EQ(ta.size(), 1u);
  EXPECT_EQ(ta[0].lease.tile.job, slow);
  EXPECT_TRUE(s.hold(slow, true));
  EXPECT_TRUE(s.held(slow));
  EXPECT_FALSE(s.hold("nope", true));
  // The held job's queued tiles are skipped, so b gets the other job; and no speculative copy
  // of the held job's leased tile 0 either, once the other job is used up.
  auto tb = pull(b, 3);
  ASSERT_EQ(tb.size(), 2u);
  for (const auto& x : tb) {
    EXPECT_EQ(x.lease.tile.job, other);
    EXPECT_EQ(s.complete(b, x.lease.id, x.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  }
  EXPECT_EQ(s.job(other)->state, JobState::kDone);
  EXPECT_FALSE(s.dispatchable());
  EXPECT_TRUE(pull(a, 1).empty());
  // A lease issued before the hold still completes.
  EXPECT_EQ(s.complete(a, ta[0].lease.id, ta[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_EQ(s.job(slow)->tiles_done, 1);
  // Released: the standing requests (a: 1, b: 1) get the held job's next tiles, in order.
  EXPECT_TRUE(s.hold(slow, false));
  EXPECT_TRUE(s.dispatchable());
  auto after = s.dispatch();
  ASSERT_EQ(after.size(), 2u);
  std::set<int> tiles;
  for (const auto& x : after) {
    EXPECT_EQ(x.lease.tile.job, slow);
    EXPECT_FALSE(x.lease.speculative);
    tiles.insert(x.lease.tile.tile);
  }
  EXPECT_EQ(tiles, (std::set<int>{1, 2}));
}

TEST_F(SchedulerTest, NothingDispatchableOnceEveryTileHasTwoCopies) {
  s.submit(spec(32, 16, 16));  // 2 tiles
  const WorkerId a = worker("a"), b = worker("b"), c = worker("c");
  ASSERT_EQ(pull(a, 2).size(), 2u);
  EXPECT_TRUE(s.dispatchable());  // both tiles have a single copy: b may duplicate them
  ASSERT_EQ(pull(b, 2).size(), 2u);
  EXPECT_FALSE(s.dispatchable());
  s.request_tiles(c, 5);
  EXPECT_TRUE(s.dispatch().empty());
  // b leaves: its copies end, so a's leases are single copies again and c may duplicate them.
  s.remove_worker(b, "test");
  EXPECT_TRUE(s.dispatchable());
  auto tc = s.dispatch();
  ASSERT_EQ(tc.size(), 2u);
  EXPECT_TRUE(tc[0].lease.speculative);
  EXPECT_EQ(tc[0].lease.tile.tile, 0);  // the oldest first
}

TEST_F(SchedulerTest, SetPriorityReordersQueuedTilesOfLiveJobsOnly) {
  const JobId low = s.submit(spec(16, 16, 16, 2, 0));
  const JobId high = s.submit(spec(16, 16, 16, 2, 5));
  const WorkerId w = worker("a");
  auto first = pull(w, 1);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].lease.tile.job, high);
  // Raising the older job above the other puts its tiles first from the next dispatch.
  EXPECT_EQ(s.set_priority(low, 9), Scheduler::PriorityResult::kChanged);
  EXPECT_EQ(s.job(low)->spec.priority, 9);
  auto next = pull(w, 1);
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].lease.tile.job, low);
  EXPECT_EQ(s.set_priority("nope", 1), Scheduler::PriorityResult::kUnknownJob);
  ASSERT_EQ(s.cancel(high), Scheduler::CancelResult::kCancelled);
  EXPECT_EQ(s.set_priority(high, 1), Scheduler::PriorityResult::kAlreadyEnded);
  EXPECT_EQ(s.job(high)->spec.priority, 5);
}

}  // namespace
}  // namespace tessera::server

namespace tessera::server {
namespace {

// A passes job (frame targets): the planner sees every tile's output when a frame's pass ends and
// sends some tiles round again with a plan; the frame's tiles are reported only after its last
// pass, and a restore starts a partly stored frame again from its first pass.
TEST_F(SchedulerTest, APassesJobReportsItsFramesOnlyAfterTheirLastPass) {
  JobSpec j = spec(32, 16, 16, 2);  // 2 tiles a frame, 2 frames
  j.passes = true;
  std::vector<std::tuple<int, int, size_t>> calls;  // frame, passes done, outputs seen
  s.set_pass_planner([&](const JobId&, int frame, int passes, const std::vector<const TileOutput*>& outs) {
    calls.emplace_back(frame, passes, outs.size());
    PassDecision d;
    if (passes == 1) {  // tile 1 goes round again with plan "p2"
      d.final = false;
      d.plans = {std::nullopt, std::string("p2")};
    }
    return d;
  });
  const JobId id = s.submit(j);
  const WorkerId w = worker("a");
  auto as = pull(w, 10);
  ASSERT_EQ(as.size(), 4u);
  for (const auto& a : as) EXPECT_EQ(a.plan, "");  // the first pass
  for (const auto& a : as) ASSERT_EQ(s.complete(w, a.lease.id, a.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_TRUE(rec.finished.empty()) << "a tile was reported before its frame's last pass";
  EXPECT_TRUE(rec.frames.empty());
  ASSERT_EQ(calls.size(), 2u);
  EXPECT_EQ(calls[0], std::make_tuple(0, 1, size_t(2)));
  EXPECT_EQ(s.job(id)->tiles_done, 2);  // tile 1 of each frame is back in the queue
  EXPECT_EQ(s.acknowledge_frame(id, 0), Scheduler::AckResult::kNotFinished);
  auto again = pull(w, 10);
  ASSERT_EQ(again.size(), 2u);
  for (const auto& a : again) {
    EXPECT_EQ(a.lease.tile.tile, 1);
    EXPECT_EQ(a.plan, "p2");
  }
  // Requeued at the front (older work than later frames' pilots): frame 1's pass went in last.
  EXPECT_EQ(again[0].lease.tile.frame, 1);
  std::swap(again[0], again[1]);
  ASSERT_EQ(s.complete(w, again[0].lease.id, again[0].lease.tile.tile, out(20)), Scheduler::ResultOutcome::kAccepted);
  ASSERT_EQ(rec.finished.size(), 2u);  // frame 0, both tiles, in order, then the frame
  EXPECT_EQ(rec.finished[0].tile, 0);
  EXPECT_EQ(rec.finished[1].tile, 1);
  EXPECT_EQ(rec.frames, std::vector<int>{0});
  EXPECT_NE(s.job(id)->state, JobState::kDone);
  ASSERT_EQ(s.complete(w, again[1].lease.id, again[1].lease.tile.tile, out(20)), Scheduler::ResultOutcome::kAccepted);
  EXPECT_EQ(s.job(id)->state, JobState::kDone);
  EXPECT_EQ(s.job(id)->rays, 4 * 10u + 2 * 20u);  // every pass's work counts
}

TEST_F(SchedulerTest, AFramesNextPassGoesBeforeLaterFramesPilots) {
  JobSpec j = spec(32, 16, 16, 3);  // 2 tiles a frame, 3 frames
  j.passes = true;
  s.set_pass_planner([](const JobId&, int, int passes, const std::vector<const TileOutput*>&) {
    PassDecision d;
    if (passes == 1) {
      d.final = false;
      d.plans = {std::string("a"), std::string("b")};
    }
    return d;
  });
  s.submit(j);
  const WorkerId w = worker("a");
  auto first = pull(w, 2);  // frame 0's pilot
  ASSERT_EQ(first.size(), 2u);
  for (const auto& a : first) ASSERT_EQ(s.complete(w, a.lease.id, a.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  auto next = pull(w, 2);
  ASSERT_EQ(next.size(), 2u);
  EXPECT_EQ(next[0].lease.tile.frame, 0);  // frame 0's second pass, not frame 1's pilot
  EXPECT_EQ(next[0].lease.tile.tile, 0);
  EXPECT_EQ(next[0].plan, "a");
  EXPECT_EQ(next[1].lease.tile.tile, 1);
  EXPECT_EQ(next[1].plan, "b");
}

TEST_F(SchedulerTest, APlannerErrorFailsTheJobSayingWhy) {
  JobSpec j = spec(16, 16, 16);
  j.passes = true;
  s.set_pass_planner([](const JobId&, int, int, const std::vector<const TileOutput*>&) {
    PassDecision d;
    d.error = "tile 0 carries no block statistics";
    return d;
  });
  const JobId id = s.submit(j);
  const WorkerId w = worker("a");
  auto as = pull(w, 1);
  ASSERT_EQ(as.size(), 1u);
  s.complete(w, as[0].lease.id, as[0].lease.tile.tile, out());
  EXPECT_EQ(s.job(id)->state, JobState::kFailed);
  EXPECT_EQ(s.job(id)->error, "frame 0: tile 0 carries no block statistics");
  EXPECT_TRUE(rec.finished.empty());
}

TEST_F(SchedulerTest, RestoreStartsAPartlyStoredPassesFrameAgain) {
  JobRecord r;
  r.id = "jp";
  r.spec = spec(32, 16, 16, 2);
  r.spec.passes = true;
  r.state = JobState::kRunning;
  r.done.push_back({0, 0, out()});  // frame 0: one of two tiles stored
  r.done.push_back({1, 0, out()});  // frame 1: both stored
  r.done.push_back({1, 1, out()});
  s.restore(r);
  auto j = s.job("jp");
  ASSERT_TRUE(j);
  EXPECT_EQ(j->tiles_done, 2);
  EXPECT_EQ(j->frames_done, std::vector<int>{1});
  EXPECT_EQ(s.queued_tiles(), 2u);
}

// A client attaching (finished_tiles) while a passes job's frame is between passes must not get
// that frame's done tiles: they are intermediate results, and the frame's last pass may change them.
TEST_F(SchedulerTest, AnAttachingClientGetsNoTileOfAFrameBetweenPasses) {
  JobSpec j = spec(32, 16, 16, 1);  // 2 tiles
  j.passes = true;
  s.set_pass_planner([](const JobId&, int, int passes, const std::vector<const TileOutput*>&) {
    PassDecision d;
    if (passes == 1) {
      d.final = false;
      d.plans = {std::nullopt, std::string("p2")};  // tile 0 keeps its pilot, tile 1 goes again
    }
    return d;
  });
  const JobId id = s.submit(j);
  const WorkerId w = worker("a");
  for (const auto& a : pull(w, 2)) ASSERT_EQ(s.complete(w, a.lease.id, a.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_TRUE(s.finished_tiles(id).empty()) << "tile 0 is done but its frame is between passes";
  EXPECT_TRUE(s.job(id)->frames_done.empty());
  auto second = pull(w, 1);
  ASSERT_EQ(second.size(), 1u);
  ASSERT_EQ(s.complete(w, second[0].lease.id, second[0].lease.tile.tile, out(20)), Scheduler::ResultOutcome::kAccepted);
  const auto tiles = s.finished_tiles(id);
  ASSERT_EQ(tiles.size(), 2u);
  EXPECT_EQ(tiles[1].second.rays, 20u) << "the last pass's output";
  EXPECT_EQ(s.job(id)->frames_done, std::vector<int>{0});
}

// A session that takes tiles and never returns one holds no more than its initial credit; a
// worker that returns results earns two more leases for each.
TEST_F(SchedulerTest, LeaseCreditBoundsWhatASessionHoldsBeforeItRenders) {
  SchedulerOptions o = opts();
  o.initial_leases_per_thread = 2;
  Scheduler sc{o, [this] { return now; }};
  sc.submit(spec(320, 320, 16));  // 400 tiles
  const WorkerId idle = sc.add_worker({"idle", "", 4, "AVX2"});
  sc.request_tiles(idle, 100);
  EXPECT_EQ(sc.dispatch().size(), 8u) << "2 per declared thread";
  EXPECT_EQ(sc.lease_credit(idle), 0);
  const WorkerId huge = sc.add_worker({"claims-many", "", 100000, "AVX2"});
  sc.request_tiles(huge, 1000);
  EXPECT_EQ(sc.dispatch().size(), size_t(2 * SchedulerOptions::kMaxCreditThreads)) << "threads are capped";
  const WorkerId honest = sc.add_worker({"honest", "", 1, "AVX2"});
  sc.request_tiles(honest, 10);
  auto mine = sc.dispatch();
  ASSERT_EQ(mine.size(), 2u);
  ASSERT_EQ(sc.complete(honest, mine[0].lease.id, mine[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
  EXPECT_EQ(sc.lease_credit(honest), 3) << "credit 2 + 2 earned, 1 still held";
  EXPECT_EQ(sc.dispatch().size(), 3u);
}

// Dispatch runs on every worker message and looks only at the workers it could serve: those that
// want tiles and hold fewer leases than their credit. Random requests, results, faults, returns,
// stalls and departures over 40 workers; after each, the set dispatch looks at is exactly the set
// the rule names (a worker at its credit re-enters it when a result, an ended lease or a new
// request gives it room, and leaves it when it has what it asked for).
TEST_F(SchedulerTest, DispatchLooksOnlyAtWorkersItCanServeWhateverHappens) {
  SchedulerOptions o = opts();
  o.initial_leases_per_thread = 1;
  o.stall_timeout = 30s;
  o.lease_timeout = 3600s;
  o.max_faults = 1 << 20;  // faults here test credit, not the blocklist
  Scheduler sc{o, [this] { return now; }};
  const JobId id = sc.submit(spec(640, 640, 16));  // 400 tiles
  std::mt19937 rng(5);
  std::vector<WorkerId> ws;
  for (int i = 0; i < 40; ++i) ws.push_back(sc.add_worker({"w" + std::to_string(i), "", 1 + i % 3, "AVX2"}));
  std::map<WorkerId, std::vector<LeaseId>> held;
  for (int step = 0; step < 3000; ++step) {
    const WorkerId w = ws[rng() % ws.size()];
    switch (rng() % 6) {
      case 0: sc.request_tiles(w, 1 + int(rng() % 5)); break;
      case 1: case 2:
        if (!held[w].empty()) {
          if (auto l = sc.lease(held[w].back())) sc.complete(w, l->id, l->tile.tile, out());
          held[w].pop_back();
        }
        break;
      case 3:  // a bad result for a lease it holds, or a stray one: both earn credit
        if (!held[w].empty() && rng() % 2) {
          sc.fault(w, id, held[w].back(), "bad");
          held[w].pop_back();
        } else {
          sc.fault(w, id, std::nullopt, "stray");
        }
        break;
      case 4:
        if (!held[w].empty()) {
          sc.return_leases(w, {held[w].back()});
          held[w].pop_back();
        }
        break;
      case 5:
        now += 11s;  // past the stall timeout for a worker idle three times in a row
        for (WorkerId x : ws) sc.heartbeat(x);
        sc.expire();
        break;
    }
    for (const Assignment& a : sc.dispatch()) held[a.lease.worker].push_back(a.lease.id);
    for (auto& [x, leases] : held) {  // leases revoked meanwhile (stalls, blocklists) are gone
      std::erase_if(leases, [&](LeaseId l) { return !sc.lease(l); });
    }
    std::vector<WorkerId> expected;
    for (WorkerId x : ws) {
      const auto st = sc.worker(x);
      if (st && st->wanted > 0 && sc.lease_credit(x) > 0) expected.push_back(x);
    }
    ASSERT_EQ(sc.wanting_workers(), expected) << "step " << step;
    if (step == 1500) {
      sc.remove_worker(ws.back(), "test");
      held.erase(ws.back());
      ws.pop_back();
    }
  }
  EXPECT_GT(sc.job(id)->tiles_done, 50) << "the run rendered: the rule was checked on a farm at work";
}

// Heartbeats keep a worker connected but not its leases: one that returns nothing for longer
// than the stall timeout loses them (requeued for others) and its credit starts again.
TEST_F(SchedulerTest, ASessionThatReturnsNothingLosesItsLeasesWhateverItsHeartbeats) {
  SchedulerOptions o = opts();
  o.stall_timeout = 30s;
  o.initial_leases_per_thread = 2;
  Scheduler sc{o, [this] { return now; }};
  const JobId id = sc.submit(spec(64, 32, 16));  // 8 tiles
  const WorkerId idle = sc.add_worker({"idle", "", 2, "AVX2"});
  const WorkerId busy = sc.add_worker({"busy", "", 1, "AVX2"});
  sc.request_tiles(idle, 3);
  ASSERT_EQ(sc.dispatch().size(), 3u);
  sc.request_tiles(busy, 1);
  auto b = sc.dispatch();
  ASSERT_EQ(b.size(), 1u);
  for (int i = 0; i < 4; ++i) {
    now += 10s;
    sc.heartbeat(idle);
    sc.heartbeat(busy);
    if (i == 1) {  // at 20 s busy returns its tile and takes the next
      ASSERT_EQ(sc.complete(busy, b[0].lease.id, b[0].lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
      sc.request_tiles(busy, 1);
      ASSERT_EQ(sc.dispatch().size(), 1u);
    }
    sc.expire();
  }
  EXPECT_EQ(sc.worker(idle)->in_flight, 0) << "40 s without a result";
  EXPECT_EQ(sc.worker(busy)->in_flight, 1) << "its last result was 20 s ago";
  EXPECT_EQ(sc.queued_tiles(), 6u) << "idle's 3 are requeued";
  ASSERT_TRUE(sc.worker(idle)) << "still connected: it only lost the work it did not do";
  EXPECT_EQ(sc.job(id)->tiles_done, 1);
  sc.request_tiles(idle, 10);
  EXPECT_EQ(sc.dispatch().size(), 4u) << "its credit started again: 2 per thread";
}

// A cancelled (or failed) job frees the tile tables of its frames that are not final at once:
// they no longer count against the resident limit, and the final ones stay deliverable.
TEST_F(SchedulerTest, ACancelledJobReleasesItsUnfinishedFramesAtOnce) {
  const JobId id = s.submit(spec(32, 16, 16, 3));  // 2 tiles a frame, 3 frames
  EXPECT_EQ(s.tiles_held(), 0) << "no frame has started";
  const WorkerId w = worker("a");
  auto as = pull(w, 3);  // frame 0 both tiles, frame 1 tile 0
  for (const auto& a : as) s.complete(w, a.lease.id, a.lease.tile.tile, out());
  EXPECT_EQ(s.tiles_held(), 4) << "frames 0 and 1 have started";
  ASSERT_EQ(s.cancel(id), Scheduler::CancelResult::kCancelled);
  EXPECT_EQ(s.tiles_held(), 2) << "frame 0 is final and not yet delivered; frames 1 and 2 are released";
  EXPECT_EQ(s.finished_tiles(id).size(), 2u);
  EXPECT_EQ(s.job(id)->frames_done, std::vector<int>{0});
  EXPECT_FALSE(s.all_acknowledged(id));
  EXPECT_EQ(s.acknowledge_frame(id, 1), Scheduler::AckResult::kNotFinished);
  EXPECT_EQ(s.acknowledge_frame(id, 0), Scheduler::AckResult::kAcknowledged);
  EXPECT_TRUE(s.all_acknowledged(id)) << "nothing left to deliver";
  EXPECT_TRUE(s.forget(id));
  EXPECT_EQ(s.tiles_held(), 0);
}

// A job's memory does not grow with its frames: a frame's tile table is built when its first
// tile goes out and freed when a client acknowledges it, so 10,000 frames of 16,384 tiles each
// (164 million: 17 GB of tile tables built at submit) cost nothing per tile until they start, and
// tiles still go out in frame and tile order with given-back tiles first.
TEST_F(SchedulerTest, AFrameCostsMemoryOnlyFromItsFirstTileToItsAcknowledgement) {
  const JobId id = s.submit(spec(512, 512, 4, 10000));
  constexpr int kPerFrame = 128 * 128;
  const auto snap = s.job(id);
  EXPECT_EQ(snap->tiles_total, int64_t(10000) * kPerFrame);
  EXPECT_EQ(s.tiles_held(), 0);
  EXPECT_EQ(s.queued_tiles(), size_t(10000) * kPerFrame);
  const WorkerId w = worker("a");
  auto first = pull(w, 3);
  ASSERT_EQ(first.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(first[size_t(i)].lease.tile.frame, 0);
    EXPECT_EQ(first[size_t(i)].lease.tile.tile, i);
  }
  EXPECT_EQ(s.tiles_held(), kPerFrame) << "frame 0's table, and only it";
  s.return_leases(w, {first[1].lease.id});
  auto again = pull(w, 2);
  ASSERT_EQ(again.size(), 2u);
  EXPECT_EQ(again[0].lease.tile.tile, 1) << "a given-back tile goes out before fresh ones";
  EXPECT_EQ(again[1].lease.tile.tile, 3);
  EXPECT_EQ(s.queued_tiles(), size_t(10000) * kPerFrame - 4);

  // A small job: every frame laid out and freed in turn.
  const JobId small = s.submit(spec(32, 16, 16, 3, /*priority=*/1));  // 2 tiles a frame
  const WorkerId v = worker("b");
  for (int frame = 0; frame < 3; ++frame) {
    auto as = pull(v, 2);
    ASSERT_EQ(as.size(), 2u);
    for (const auto& a : as) {
      EXPECT_EQ(a.lease.tile.job, small);
      EXPECT_EQ(a.lease.tile.frame, frame);
      ASSERT_EQ(s.complete(v, a.lease.id, a.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
    }
    EXPECT_EQ(s.job(small)->tiles_resident, 2);
    EXPECT_EQ(s.acknowledge_frame(small, frame), Scheduler::AckResult::kAcknowledged);
    EXPECT_EQ(s.job(small)->tiles_resident, 0);
  }
  EXPECT_EQ(s.job(small)->state, JobState::kDone);
  EXPECT_EQ(s.job(small)->tiles_done, 6);
  EXPECT_TRUE(s.all_acknowledged(small));
}

// Under the memory limits a job whose next frame does not fit waits, says so, and starts it as
// soon as a client's acknowledgement (or another job's end) makes room: of one job, and of all.
TEST_F(SchedulerTest, AJobWaitsForMemoryAndStartsItsNextFrameWhenAFrameIsAcknowledged) {
  SchedulerOptions o = opts();
  o.max_job_tiles = 4;        // two frames of 2 tiles
  o.max_resident_tiles = 6;   // three
  o.speculate = false;        // idle workers would take second copies of the tiles in flight
  Scheduler sc{o, [this] { return now; }, [this] { return "job" + std::to_string(++next_id); }};
  const JobId a = sc.submit(spec(32, 16, 16, 4));  // 2 tiles a frame, 4 frames
  const WorkerId w = sc.add_worker({"w", "", 1, "AVX2"});
  const auto render = [&](int n) {
    sc.request_tiles(w, n);
    auto as = sc.dispatch();
    for (const auto& x : as) EXPECT_EQ(sc.complete(w, x.lease.id, x.lease.tile.tile, out()), Scheduler::ResultOutcome::kAccepted);
    return as;
  };
  EXPECT_EQ(render(10).size(), 4u) << "frames 0 and 1; frame 2 would hold 6 tiles of the job";
  EXPECT_TRUE(sc.job(a)->waiting_for_memory);
  EXPECT_EQ(sc.queued_tiles(), 4u) << "waiting tiles are still queued";
  EXPECT_FALSE(sc.dispatchable());
  ASSERT_EQ(sc.acknowledge_frame(a, 0), Scheduler::AckResult::kAcknowledged);
  EXPECT_FALSE(sc.job(a)->waiting_for_memory);
  auto next = sc.dispatch();  // the standing request is served at once
  ASSERT_EQ(next.size(), 2u);
  EXPECT_EQ(next[0].lease.tile.frame, 2);

  // Another job: 4 tiles of `a` held (frames 1 and 2), so one frame of `b` fits the farm's 6.
  const JobId b = sc.submit(spec(32, 16, 16, 2, /*priority=*/1));
  const WorkerId v = sc.add_worker({"v", "", 1, "AVX2"});
  sc.request_tiles(v, 4);
  auto bs = sc.dispatch();
  ASSERT_EQ(bs.size(), 2u) << "frame 0 of b; its frame 1 would take the farm to 8";
  EXPECT_TRUE(sc.job(b)->waiting_for_memory);
  for (const auto& x : next) sc.complete(w, x.lease.id, x.lease.tile.tile, out());
  ASSERT_EQ(sc.cancel(a), Scheduler::CancelResult::kCancelled);  // frame 3 never started
  EXPECT_TRUE(sc.job(b)->waiting_for_memory) << "a's final frames 1 and 2 are not yet delivered";
  ASSERT_TRUE(sc.acknowledge_frame(a, 1) == Scheduler::AckResult::kAcknowledged);
  EXPECT_FALSE(sc.job(b)->waiting_for_memory);
  auto rest = sc.dispatch();
  ASSERT_EQ(rest.size(), 2u);
  EXPECT_EQ(rest[0].lease.tile.job, b);
  EXPECT_EQ(rest[0].lease.tile.frame, 1);
  EXPECT_EQ(sc.tiles_held(), 6);
}

// Model-based: random interleavings of workers (fast, slow, dying), speculation, clients
// attaching, acknowledging and a restart from what the store was told, on passes jobs and
// fixed-spp jobs. A tile's output is a pure function of (frame, tile, plan), as a worker's is, so
// the one rule can be checked exactly: every tile a client receives (attaching or live) is the
// tile's final output.
struct Delivery : SchedulerListener {
  std::map<std::tuple<int, int>, uint64_t> live;  // tile_finished: (frame, tile) -> rays
  std::vector<RestoredTile> stored;                 // what a JobStore would hold
  void tile_finished(const TileKey& k, const TileOutput& o, WorkerId) override {
    live[{k.frame, k.tile}] = o.rays;
    stored.push_back({k.frame, k.tile, o});
  }
};

TEST(SchedulerModel, EveryTileAClientReceivesIsFinalInEveryInterleaving) {
  for (uint32_t seed = 1; seed <= 300; ++seed) {
    std::mt19937 rng(seed);
    TimePoint now{};
    SchedulerOptions o;
    o.lease_timeout = 10s;
    o.stall_timeout = 20s;
    auto sched = std::make_unique<Scheduler>(o, [&] { return now; }, [] { return JobId("j"); });
    Delivery d;
    sched->set_listener(&d);
    // Output of a tile at a plan: passes - 1 plans deep; final when the planner says so.
    const bool passes = seed % 3 != 0;
    const int max_passes = 1 + int(seed % 4);
    auto planner = [&](const JobId&, int frame, int done, const std::vector<const TileOutput*>&) {
      PassDecision dec;
      if (done < max_passes) {
        dec.final = false;
        dec.plans.resize(4);
        for (int t = 0; t < 4; ++t) {
          if ((t + frame + done) % 2 == 0) dec.plans[size_t(t)] = std::to_string(done);
        }
      }
      return dec;
    };
    sched->set_pass_planner(planner);
    JobSpec spec;
    spec.width = spec.height = 32;
    spec.tile_size = 16;
    spec.last_frame = 2;
    spec.spp = 4;
    spec.passes = passes;
    const JobId id = sched->submit(spec);
    // The final output of every tile, computed from the plan each tile last rendered at.
    auto output = [](int frame, int tile, const std::string& plan) {
      return TileOutput{std::make_shared<const std::string>("x"), uint64_t(1000 * frame + 10 * tile) +
                                                                       (plan.empty() ? 0 : 1 + std::stoull(plan)),
                        0.01};
    };
    auto final_rays = [&](int frame, int tile) {
      if (!passes) return uint64_t(1000 * frame + 10 * tile);
      int last = -1;  // the last planned pass that re-rendered this tile (plans "1", "2", ...)
      for (int p = 1; p < max_passes; ++p) {
        if ((tile + frame + p) % 2 == 0) last = p;
      }
      return uint64_t(1000 * frame + 10 * tile) + (last < 0 ? 0 : 1 + uint64_t(last));
    };
    std::vector<WorkerId> ws;
    std::map<LeaseId, Assignment> held;
    std::set<int> acked;
    auto check = [&](const char* where) {
      for (const auto& [key, out] : sched->finished_tiles(id)) {
        ASSERT_EQ(out.rays, final_rays(key.frame, key.tile))
            << "seed " << seed << ", " << where << ": frame " << key.frame << " tile " << key.tile;
      }
      for (const auto& [k, rays] : d.live) {
        ASSERT_EQ(rays, final_rays(std::get<0>(k), std::get<1>(k))) << "seed " << seed << " (live)";
      }
    };
    for (int step = 0; step < 400; ++step) {
      const int action = int(rng() % 10);
      if (action == 0 || ws.empty()) {
        ws.push_back(sched->add_worker({"w" + std::to_string(rng() % 4), "", 1, "AVX2"}));
      } else if (action <= 2) {
        const WorkerId w = ws[rng() % ws.size()];
        sched->request_tiles(w, 1 + int(rng() % 3));
        for (auto& a : sched->dispatch()) held[a.lease.id] = a;
      } else if (action <= 5 && !held.empty()) {
        auto it = std::next(held.begin(), long(rng() % held.size()));
        const Assignment a = it->second;
        held.erase(it);
        sched->complete(a.lease.worker, a.lease.id, a.lease.tile.tile, output(a.lease.tile.frame, a.lease.tile.tile, a.plan));
      } else if (action == 6) {
        check("attach");
      } else if (action == 7) {
        for (const auto& [key, out] : sched->finished_tiles(id)) {
          if (sched->acknowledge_frame(id, key.frame) == Scheduler::AckResult::kAcknowledged) acked.insert(key.frame);
        }
      } else if (action == 8) {
        now += std::chrono::seconds(rng() % 12);
        for (WorkerId w : ws) {
          if (rng() % 2) sched->heartbeat(w);
        }
        for (WorkerId gone : sched->expire()) std::erase(ws, gone);
      } else if (action == 9 && rng() % 8 == 0) {
        // Restart: a new scheduler from what the store holds (done tiles as they were reported,
        // the acknowledged frames); leases in flight are lost.
        JobRecord r;
        r.id = id;
        r.spec = spec;
        r.state = JobState::kRunning;
        r.done = d.stored;
        r.acknowledged.assign(acked.begin(), acked.end());
        sched = std::make_unique<Scheduler>(o, [&] { return now; }, [] { return JobId("j"); });
        sched->set_listener(&d);
        sched->set_pass_planner(planner);
        sched->restore(r);
        ws.clear();
        held.clear();
        check("restart");
      }
      if (HasFatalFailure()) return;
    }
    check("end");
    if (HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace tessera::server

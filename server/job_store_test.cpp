// JobStore: what is written comes back after reopening (the restart path), leases in flight
// come back as queued tiles, a broken database or an unwritable directory stops the store with
// a message naming the file.
#include "job_store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <unistd.h>

#include <fstream>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

class JobStoreTest : public ::testing::Test {
 protected:
  fs::path dir;
  void SetUp() override {
    std::string t = (fs::temp_directory_path() / "tessera-store-XXXXXX").string();
    ASSERT_NE(mkdtemp(t.data()), nullptr);
    dir = t;
  }
  void TearDown() override { fs::remove_all(dir); }

  static JobSnapshot job(const std::string& id, uint64_t seq) {
    JobSnapshot s;
    s.id = id;
    s.seq = seq;
    s.spec.name = "scene.json";
    s.spec.bundle_sha256 = std::string(64, 'a');
    s.spec.overrides = std::string("\x08\x02\0x", 4);  // arbitrary bytes, including a NUL
    s.spec.first_frame = 5;
    s.spec.last_frame = 6;
    s.spec.width = 40;
    s.spec.height = 20;
    s.spec.spp = 4;
    s.spec.tile_size = 16;  // 3x2 = 6 tiles a frame
    s.spec.priority = 7;
    s.state = JobState::kRunning;
    s.submitted = Clock::now();
    return s;
  }
  static TileOutput out(const std::string& bytes, uint64_t rays) {
    return {std::make_shared<const std::string>(bytes), rays, 0.25};
  }
};

TEST_F(JobStoreTest, RoundTripsJobsTilesAcksAndLeases) {
  {
    JobStore store(dir);
    EXPECT_TRUE(store.load().jobs.empty());
    store.job_submitted(job("j1", 1));
    store.job_submitted(job("j2", 2));
    for (int t = 0; t < 6; ++t) store.tile_done({"j1", 5, t}, out("f5t" + std::to_string(t), 10));
    store.tile_done({"j1", 6, 2}, out("f6t2", 100));
    store.frame_acknowledged("j1", 5, 6);
    Lease l;
    l.id = 41;
    l.tile = {"j1", 6, 3};
    l.issued = Clock::now();
    store.lease_issued(l, "w1");
    Lease transient = l;
    transient.id = 42;
    store.lease_issued(transient, "w1");
    store.lease_ended(42);
    ASSERT_EQ(store.barrier().get(), "");
    // The acknowledged frame's files are gone, the other tile's file is there.
    EXPECT_FALSE(fs::exists(dir / "tiles" / "j1" / "5-0.tile"));
    EXPECT_TRUE(fs::exists(dir / "tiles" / "j1" / "6-2.tile"));
  }
  // An orphan: a file written but never committed (crash between the two).
  { std::ofstream(dir / "tiles" / "j1" / "6-4.tile") << "orphan"; }
  { std::ofstream(dir / "tiles" / "j1" / "6-5.tile.tmp") << "half"; }
  JobStore store(dir);
  JobStore::Loaded l = store.load();
  ASSERT_EQ(l.jobs.size(), 2u);
  EXPECT_EQ(l.jobs[0].id, "j1");
  EXPECT_EQ(l.jobs[1].id, "j2");
  const JobRecord& r = l.jobs[0];
  EXPECT_EQ(r.spec.overrides, std::string("\x08\x02\0x", 4));
  EXPECT_EQ(r.spec.first_frame, 5);
  EXPECT_EQ(r.spec.priority, 7);
  EXPECT_EQ(r.state, JobState::kRunning);
  EXPECT_EQ(r.acknowledged, std::vector<int>{5});
  ASSERT_EQ(r.done.size(), 7u);
  // Acknowledged frame: stats without pixels; unacknowledged: the bytes as written.
  EXPECT_EQ(r.done[0].output.payload, nullptr);
  EXPECT_EQ(r.done[6].frame, 6);
  EXPECT_EQ(r.done[6].tile, 2);
  ASSERT_NE(r.done[6].output.payload, nullptr);
  EXPECT_EQ(*r.done[6].output.payload, "f6t2");
  EXPECT_EQ(r.done[6].output.rays, 100u);
  // One lease was in flight (42 began and ended in one batch and was never written); lease ids
  // continue after the highest ever issued.
  EXPECT_EQ(l.leases_requeued, 1);
  EXPECT_EQ(l.next_lease, 43u);
  EXPECT_EQ(l.orphans_removed, 2);
  EXPECT_FALSE(fs::exists(dir / "tiles" / "j1" / "6-4.tile"));
  EXPECT_TRUE(fs::exists(dir / "tiles" / "j1" / "6-2.tile"));
}

TEST_F(JobStoreTest, RestoredJobRequeuesEverythingNotDone) {
  {
    JobStore store(dir);
    store.load();
    store.job_submitted(job("j1", 1));
    store.tile_done({"j1", 6, 2}, out("x", 1));
    ASSERT_EQ(store.barrier().get(), "");
  }
  JobStore store(dir);
  auto l = store.load();
  ASSERT_EQ(l.jobs.size(), 1u);
  Scheduler s;
  s.restore(l.jobs[0]);
  auto snap = s.job("j1");
  ASSERT_TRUE(snap);
  EXPECT_EQ(snap->tiles_done, 1);
  EXPECT_EQ(s.queued_tiles(), 11u);  // 2 frames x 6 tiles, minus the done one
  auto tiles = s.finished_tiles("j1");
  ASSERT_EQ(tiles.size(), 1u);
  EXPECT_EQ(*tiles[0].second.payload, "x");
}

TEST_F(JobStoreTest, EvictedJobIsQueryableButNotLoaded) {
  {
    JobStore store(dir);
    store.load();
    JobSnapshot s = job("j1", 1);
    store.job_submitted(s);
    s.state = JobState::kDone;
    s.ended = Clock::now();
    store.job_updated(s);
    store.job_evicted("j1");
    ASSERT_EQ(store.barrier().get(), "");
    auto q = store.read_job("j1");
    ASSERT_TRUE(q);
    EXPECT_EQ(q->state, JobState::kDone);
    EXPECT_EQ(q->tiles_total, 12);
    EXPECT_FALSE(store.read_job("nope"));
  }
  JobStore store(dir);
  EXPECT_TRUE(store.load().jobs.empty());
}

TEST_F(JobStoreTest, GarbageDatabaseIsRefusedNamingTheFile) {
  { std::ofstream(dir / "tessera.db") << std::string(8192, 'G'); }
  try {
    JobStore store(dir);
    FAIL() << "a garbage database was accepted";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "tessera.db").string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("corrupt"), std::string::npos) << e.what();
  }
}

TEST_F(JobStoreTest, UnknownSchemaVersionIsRefused) {
  { JobStore store(dir); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "tessera.db").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE schema_version SET version=99", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    JobStore store(dir);
    FAIL() << "schema version 99 was accepted";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 99"), std::string::npos) << e.what();
  }
}

TEST_F(JobStoreTest, DataDirThatIsAFileIsRefused) {
  { std::ofstream(dir / "file") << "x"; }
  try {
    JobStore store(dir / "file" / "data");
    FAIL() << "accepted";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "file" / "data").string()), std::string::npos) << e.what();
  }
}

TEST_F(JobStoreTest, ReadOnlyDataDirIsRefused) {
  if (geteuid() == 0) GTEST_SKIP() << "root ignores directory permissions (the farm test covers a read-only mount)";
  fs::create_directories(dir / "ro");
  fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
  try {
    JobStore store(dir / "ro");
    FAIL() << "accepted";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("not writable"), std::string::npos) << e.what();
  }
  fs::permissions(dir / "ro", fs::perms::owner_all);
}

}  // namespace
}  // namespace tessera::server

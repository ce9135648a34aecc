// SPDX-License-Identifier: Apache-2.0
// JobStore: what is written comes back after reopening (the restart path), leases in flight
// come back as queued tiles, a broken database or an unwritable directory stops the store with
// a message naming the file.
#include "job_store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <future>
#include <map>
#include <set>
#include <thread>
#include <tuple>

#include "job_summary.h"
#include "tessera/v1/common.pb.h"

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
    s.spec.owner = "ipv4:127.0.0.1";
    s.state = JobState::kRunning;
    s.submitted = Clock::now();
    return s;
  }
  static TileOutput out(const std::string& bytes, uint64_t rays) {
    return {std::make_shared<const std::string>(bytes), rays, 0.25};
  }
  static Lease lease(LeaseId id, const TileKey& tile) {
    Lease l;
    l.id = id;
    l.tile = tile;
    l.issued = Clock::now();
    return l;
  }
  // The segment numbers of the *.seg files in tiles/.
  std::set<int64_t> segment_files() const {
    std::set<int64_t> s;
    for (const auto& e : fs::directory_iterator(dir / "tiles")) {
      const std::string name = e.path().filename().string();
      if (name.size() > 4 && name.ends_with(".seg")) s.insert(std::stoll(name.substr(0, name.size() - 4)));
    }
    return s;
  }
  // Read from the database directly, independently of JobStore.
  std::vector<std::vector<int64_t>> rows(const std::string& sql) const {
    sqlite3* db = nullptr;
    EXPECT_EQ(sqlite3_open((dir / "tessera.db").c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
    std::vector<std::vector<int64_t>> out;
    while (sqlite3_step(st) == SQLITE_ROW) {
      std::vector<int64_t> r;
      for (int i = 0; i < sqlite3_column_count(st); ++i) r.push_back(sqlite3_column_int64(st, i));
      out.push_back(r);
    }
    sqlite3_finalize(st);
    sqlite3_close(db);
    return out;
  }
  std::set<int64_t> segments_of(const std::string& job, int frame) const {
    std::set<int64_t> s;
    for (const auto& r : rows("SELECT segment FROM tiles WHERE job='" + job + "' AND frame=" + std::to_string(frame)))
      s.insert(r[0]);
    return s;
  }
  std::pair<int64_t, int64_t> location_of(const std::string& job, int frame, int tile) const {
    auto r = rows("SELECT segment, offset FROM tiles WHERE job='" + job + "' AND frame=" + std::to_string(frame) +
                  " AND tile=" + std::to_string(tile));
    if (r.size() != 1) return {-1, -1};
    return {r[0][0], r[0][1]};
  }
  int64_t max_segment_ever() const {
    return rows("SELECT max(coalesce((SELECT max(segment) FROM tiles), 0), "
                "coalesce((SELECT value FROM meta WHERE key='segment_hwm'), 0))")[0][0];
  }
  // Rows of a table that belong to `job`.
  int64_t rows_of(const char* table, const std::string& job) const {
    return rows(std::string("SELECT count(*) FROM ") + table + " WHERE job='" + job + "'")[0][0];
  }
  // Waits (up to 20 s) until the store has shed the rows of every evicted job.
  static bool shed(JobStore& store) {
    for (int i = 0; i < 2000 && store.stats().jobs_to_shed > 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return store.stats().jobs_to_shed == 0;
  }
  // What `tessera status JOB` shows of a job read from the database.
  static std::tuple<JobState, int64_t, std::vector<int>, std::vector<int>> status(const JobSnapshot& s) {
    return {s.state, s.tiles_done, s.frames_done, s.frames_acknowledged};
  }
  // `dir` becomes a copy of the data directory the previous release wrote (tests/data/datadir-previous).
  void copy_previous_release() const {
    fs::remove_all(dir);
    fs::copy(fs::path(TESSERA_SOURCE_DIR) / "tests/data/datadir-previous/data", dir, fs::copy_options::recursive);
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
    const Lease l = lease(41, {"j1", 6, 3});
    store.lease_issued(l, "w1");
    Lease transient = l;
    transient.id = 42;
    store.lease_issued(transient, "w1");
    store.lease_ended(42);
    ASSERT_EQ(store.barrier().get(), "");
    // Only the segment(s) holding frame 6's tile are left: frame 5 is acknowledged.
    EXPECT_EQ(segment_files(), segments_of("j1", 6));
  }
  // Orphans: a segment written but never committed (crash between the two), and a stray file.
  { std::ofstream(dir / "tiles" / "1000.seg") << "orphan"; }
  { std::ofstream(dir / "tiles" / "notes.txt") << "stray"; }
  JobStore store(dir);
  JobStore::Loaded l = store.load();
  ASSERT_EQ(l.jobs.size(), 2u);
  EXPECT_EQ(l.jobs[0].id, "j1");
  EXPECT_EQ(l.jobs[1].id, "j2");
  const JobRecord& r = l.jobs[0];
  EXPECT_EQ(r.spec.overrides, std::string("\x08\x02\0x", 4));
  EXPECT_EQ(r.spec.first_frame, 5);
  EXPECT_EQ(r.spec.priority, 7);
  EXPECT_EQ(r.spec.owner, "ipv4:127.0.0.1");
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
  EXPECT_FALSE(fs::exists(dir / "tiles" / "1000.seg"));
  EXPECT_FALSE(fs::exists(dir / "tiles" / "notes.txt"));
  EXPECT_EQ(segment_files(), segments_of("j1", 6));
}

// Tiles of several frames and jobs share segments; a segment goes only when its last
// unacknowledged frame is acknowledged (or its job evicted), also when that happens after a
// restart (the bookkeeping is rebuilt from the rows), and segment numbers are never reused.
TEST_F(JobStoreTest, SegmentsAreSharedAndDeletedWithTheirLastFrame) {
  std::set<int64_t> f6;
  {
    JobStore store(dir);
    store.load();
    store.job_submitted(job("j1", 1));
    store.job_submitted(job("j2", 2));
    // A big tile first keeps the writer busy while the rest is queued, so the rest lands in one
    // or two batches; interleaved as results arrive, so frames and jobs share segments.
    store.tile_done({"j2", 6, 0}, out(std::string(32 << 20, 'b'), 1));
    for (int t = 0; t < 6; ++t) {
      store.tile_done({"j1", 5, t}, out("j1f5t" + std::to_string(t), 1));
      store.tile_done({"j1", 6, t}, out("j1f6t" + std::to_string(t), 1));
      store.tile_done({"j2", 5, t}, out("j2f5t" + std::to_string(t), 1));
    }
    ASSERT_EQ(store.barrier().get(), "");
    auto shared = segments_of("j1", 5);
    std::erase_if(shared, [&](int64_t s) { return !segments_of("j1", 6).count(s); });
    ASSERT_FALSE(shared.empty()) << "no segment holds tiles of both frames: the test did not test sharing";
    // j1 frame 5 acknowledged: exactly the segments still holding a tile of another frame stay,
    // among them those shared with frame 5.
    store.frame_acknowledged("j1", 5, 6);
    ASSERT_EQ(store.barrier().get(), "");
    auto needed = segments_of("j1", 6);
    for (int64_t s : segments_of("j2", 5)) needed.insert(s);
    for (int64_t s : segments_of("j2", 6)) needed.insert(s);
    EXPECT_EQ(segment_files(), needed);
    for (int64_t s : shared) EXPECT_TRUE(needed.count(s));
    // j2 evicted: the segments are still needed by j1 frame 6.
    store.job_evicted("j2");
    ASSERT_EQ(store.barrier().get(), "");
    f6 = segments_of("j1", 6);
    EXPECT_EQ(segment_files(), f6);
  }
  {
    JobStore store(dir);
    auto l = store.load();
    EXPECT_EQ(l.orphans_removed, 0);
    ASSERT_EQ(l.jobs.size(), 1u);
    int with_pixels = 0;
    for (const auto& t : l.jobs[0].done) {
      if (!t.output.payload) continue;
      ++with_pixels;
      EXPECT_EQ(*t.output.payload, "j1f6t" + std::to_string(t.tile));
    }
    EXPECT_EQ(with_pixels, 6);
    // A new tile goes to a segment numbered above every earlier one.
    const int64_t prev = max_segment_ever();
    store.tile_done({"j1", 5, 0}, out("again", 1));
    ASSERT_EQ(store.barrier().get(), "");
    const auto now = segment_files();
    ASSERT_EQ(now.size(), f6.size() + 1);
    EXPECT_GT(*now.rbegin(), prev);
    // Frame 6 acknowledged after the restart: its segments go, the new one stays.
    store.frame_acknowledged("j1", 6, 6);
    ASSERT_EQ(store.barrier().get(), "");
    EXPECT_EQ(segment_files(), std::set<int64_t>{*now.rbegin()});
    store.frame_acknowledged("j1", 5, 6);
    ASSERT_EQ(store.barrier().get(), "");
    EXPECT_TRUE(segment_files().empty());
  }
}

// At start, every segment no committed row needs is deleted, the rest are read back with their
// length and CRC checked: a damaged record is re-rendered, not served.
TEST_F(JobStoreTest, OrphanSegmentsAreRemovedAndDamagedRecordsRerendered) {
  {
    JobStore store(dir);
    store.load();
    store.job_submitted(job("j1", 1));
    store.tile_done({"j1", 5, 0}, out("acked", 1));
    store.tile_done({"j1", 6, 0}, out("kept-tile", 1));
    store.tile_done({"j1", 6, 1}, out("damaged", 1));
    ASSERT_EQ(store.barrier().get(), "");
    store.frame_acknowledged("j1", 5, 6);
    ASSERT_EQ(store.barrier().get(), "");
  }
  const auto before = segment_files();
  // A crash after a segment's sync but before its commit leaves a segment no row points into;
  // so does a crash between an acknowledgement's commit and the unlink (simulated by a copy of
  // a live segment under an unused number), and schema version 1 left job directories.
  const int64_t stray = max_segment_ever() + 5;
  fs::copy_file(dir / "tiles" / (std::to_string(*before.begin()) + ".seg"),
                dir / "tiles" / (std::to_string(stray) + ".seg"));
  fs::create_directories(dir / "tiles" / "j1");
  { std::ofstream(dir / "tiles" / "j1" / "6-0.tile") << "old"; }
  // Damage one byte of the tile "damaged": its CRC no longer matches.
  const auto [seg, off] = location_of("j1", 6, 1);
  {
    std::fstream f(dir / "tiles" / (std::to_string(seg) + ".seg"), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(off + 12 + 2);
    f.put('X');
  }
  // The damaged tile's segment is also an orphan once its row is dropped, unless it holds
  // the kept tile too (batching decides).
  const bool damaged_alone = seg != location_of("j1", 6, 0).first;
  JobStore store(dir);
  auto l = store.load();
  // The stray segment, the old directory and its file (and the damaged tile's segment).
  EXPECT_EQ(l.orphans_removed, damaged_alone ? 4 : 3);
  EXPECT_FALSE(fs::exists(dir / "tiles" / (std::to_string(stray) + ".seg")));
  EXPECT_FALSE(fs::exists(dir / "tiles" / "j1"));
  EXPECT_EQ(segment_files(), std::set<int64_t>{location_of("j1", 6, 0).first});
  EXPECT_EQ(l.tiles_missing, 1);
  ASSERT_EQ(l.jobs.size(), 1u);
  std::map<std::pair<int, int>, std::string> got;
  for (const auto& t : l.jobs[0].done) got[{t.frame, t.tile}] = t.output.payload ? *t.output.payload : "(none)";
  EXPECT_EQ(got, (std::map<std::pair<int, int>, std::string>{{{5, 0}, "(none)"}, {{6, 0}, "kept-tile"}}));
}

// A data directory written by tessera-server 1bf2db9 (tests/data/datadir-previous/README.md says
// how) reads back whole with this release: the schema is taken as it is, the jobs come back with
// their states and specs, and every stored tile passes its record's length and CRC-32 check, is
// the tile its row names and has its rectangle's pixel count. A change that makes this release
// misread what the previous one wrote (schema, rows, segment records, the checksum) fails here.
TEST_F(JobStoreTest, ReadsADataDirWrittenByThePreviousRelease) {
  copy_previous_release();
  const std::string a = "274c9bcc6306", b = "3c6f8f7123b3", c = "c44b713d704a", d = "5f56229c862f";
  const std::string bundle = "257a4b5bff42ac80cf2198d989833f92007f0c7e05398c7bd6d289bd83d75ae9";
  JobStore store(dir);
  // What the coordinator checks: the payload is the TileData of the tile its row names.
  std::map<std::pair<int, int>, tessera::v1::TileData> tiles;
  JobStore::Loaded l = store.load([&](const TileKey& row, const std::string& payload) -> std::string {
    tessera::v1::TileData t;
    if (!t.ParseFromString(payload)) return "it does not parse as a tile";
    if (t.job_id() != row.job || t.frame() != row.frame || t.tile_index() != row.tile) return "another tile";
    tiles[{row.frame, row.tile}] = t;
    return {};
  });
  EXPECT_EQ(l.tiles_missing, 0) << "stored tiles failed their length, CRC-32 or identity check";
  EXPECT_EQ(l.orphans_removed, 0);
  EXPECT_EQ(l.leases_requeued, 0);
  EXPECT_EQ(l.next_lease, 46u);  // 45 tiles were leased (jobs A and B)
  // Job B was fetched and left memory: not loaded, but its row answers.
  ASSERT_EQ(l.jobs.size(), 3u);
  const JobRecord& ja = l.jobs[0];
  const JobRecord& jc = l.jobs[1];
  const JobRecord& jd = l.jobs[2];
  EXPECT_EQ(ja.id, a);
  EXPECT_EQ(jc.id, c);
  EXPECT_EQ(jd.id, d);
  EXPECT_EQ(ja.state, JobState::kDone);
  EXPECT_EQ(jc.state, JobState::kQueued);
  EXPECT_EQ(jd.state, JobState::kCancelled);
  EXPECT_TRUE(ja.ended.has_value());
  EXPECT_FALSE(jc.ended.has_value());
  EXPECT_TRUE(jd.ended.has_value());
  EXPECT_EQ(ja.seq, 1u);
  EXPECT_EQ(jc.seq, 3u);
  EXPECT_EQ(jd.seq, 4u);
  EXPECT_LT(ja.submitted, jc.submitted);
  for (const JobRecord* r : {&ja, &jc, &jd}) {
    EXPECT_EQ(r->spec.bundle_sha256, bundle);
    EXPECT_EQ(r->spec.width, 72);
    EXPECT_EQ(r->spec.height, 40);
    EXPECT_EQ(r->spec.spp, 2);
    EXPECT_EQ(r->spec.tile_size, 16);
    EXPECT_EQ(r->spec.owner, "ipv4:127.0.0.1");
    EXPECT_FALSE(r->spec.overrides.empty());
    EXPECT_EQ(r->error, "");
    EXPECT_TRUE(r->acknowledged.empty());
    EXPECT_TRUE(r->blocklisted.empty());
  }
  EXPECT_EQ(ja.spec.name, "job-a");
  EXPECT_EQ(jc.spec.name, "job-c");
  EXPECT_EQ(jd.spec.name, "job-d");
  EXPECT_EQ(std::make_pair(ja.spec.first_frame, ja.spec.last_frame), std::make_pair(0, 1));
  EXPECT_EQ(std::make_pair(jc.spec.first_frame, jc.spec.last_frame), std::make_pair(0, 2));
  EXPECT_EQ(std::make_pair(jd.spec.first_frame, jd.spec.last_frame), std::make_pair(1, 1));
  EXPECT_EQ(ja.spec.priority, 0);
  EXPECT_EQ(jc.spec.priority, 3);
  EXPECT_TRUE(jc.done.empty());
  EXPECT_TRUE(jd.done.empty());
  // Job A: both frames done, not fetched: 2 x 15 tiles with their pixels, 5 x 3 tiles a frame
  // (72 x 40 in 16-pixel tiles: the last column 8 wide, the last row 8 high).
  ASSERT_EQ(ja.done.size(), 30u);
  ASSERT_EQ(tiles.size(), 30u);
  for (const RestoredTile& t : ja.done) {
    SCOPED_TRACE("frame " + std::to_string(t.frame) + " tile " + std::to_string(t.tile));
    ASSERT_NE(t.output.payload, nullptr);
    EXPECT_GT(t.output.rays, 0u);
    const tessera::v1::TileData& data = tiles.at({t.frame, t.tile});
    const int x0 = (t.tile % 5) * 16, y0 = (t.tile / 5) * 16;
    const int w = std::min(16, 72 - x0), h = std::min(16, 40 - y0);
    EXPECT_EQ(data.rect().x0(), x0);
    EXPECT_EQ(data.rect().y0(), y0);
    EXPECT_EQ(data.rect().width(), w);
    EXPECT_EQ(data.rect().height(), h);
    EXPECT_EQ(data.rgb().size(), size_t(3 * w * h) * sizeof(float));
    EXPECT_EQ(data.variance().size(), size_t(w * h) * sizeof(float));
    EXPECT_EQ(data.worker(), "w1");
  }
  const auto jb = store.read_job(b);
  ASSERT_TRUE(jb.has_value());
  EXPECT_EQ(jb->state, JobState::kDone);
  EXPECT_EQ(jb->spec.name, "job-b");
  EXPECT_EQ(jb->tiles_total, 15);
  EXPECT_EQ(jb->tiles_done, 15);
  EXPECT_EQ(jb->frames_done, std::vector<int>{2});
  EXPECT_EQ(jb->frames_acknowledged, std::vector<int>{2});
  EXPECT_GT(jb->rays, 0u);
  // This release writes on into it: a new tile lands in a segment numbered above every one the
  // previous release used (job B's were 3 to 5), and everything reads back after a restart.
  store.tile_done({c, 0, 0}, out("new", 1));
  ASSERT_EQ(store.barrier().get(), "");
  EXPECT_EQ(segment_files(), (std::set<int64_t>{1, 2, 6}));
}

TEST_F(JobStoreTest, DataDirOfThePreviousReleaseReadsBackAfterThisOneWroteToIt) {
  copy_previous_release();
  {
    JobStore store(dir);
    store.load();
    store.tile_done({"c44b713d704a", 0, 0}, out("new", 1));
    store.frame_acknowledged("274c9bcc6306", 0, 15);
    ASSERT_EQ(store.barrier().get(), "");
  }
  JobStore store(dir);
  JobStore::Loaded l = store.load();
  EXPECT_EQ(l.tiles_missing, 0);
  ASSERT_EQ(l.jobs.size(), 3u);
  EXPECT_EQ(l.jobs[0].acknowledged, std::vector<int>{0});
  int with_pixels = 0;
  for (const RestoredTile& t : l.jobs[0].done) with_pixels += t.output.payload != nullptr;
  EXPECT_EQ(with_pixels, 15);  // frame 1's
  ASSERT_EQ(l.jobs[1].done.size(), 1u);
  EXPECT_EQ(*l.jobs[1].done[0].output.payload, "new");
}

// The tile records' checksum is the standard CRC-32 (IEEE 802.3, reflected, as zlib and PNG
// compute it): its check value, and the empty input.
TEST(TileStoreCrc, IsTheStandardCrc32) {
  EXPECT_EQ(crc32_ieee("123456789", 9), 0xCBF43926u);
  EXPECT_EQ(crc32_ieee("", 0), 0u);
  EXPECT_EQ(crc32_ieee("The quick brown fox jumps over the lazy dog", 43), 0x414FA339u);
}

// Records written now carry XXH3-64 (libxxhash, seed 0): its documented value for the empty
// input, and a record written by the store is read back, and refused naming the hash once a bit
// of it flips.
TEST(TileStoreHash, RecordsCarryXxh3AndADamagedOneIsNamed) {
  EXPECT_EQ(xxh3_64("", 0), 0x2D06800538D394C2ull);
  const fs::path root = fs::temp_directory_path() / ("tessera-tilestore-" + std::to_string(::getpid()));
  fs::remove_all(root);
  {
    TileStore store(root);
    const std::string a(20000, 'a'), b = "second tile";
    const auto at = store.append({&a, &b});
    ASSERT_EQ(at.size(), 2u);
    EXPECT_EQ(at[1].offset, at[0].offset + 16 + int64_t(a.size()));  // 16-byte header
    EXPECT_EQ(store.read(at[1]).bytes.value_or("?"), b);
    // The next batch appends to the same segment.
    const auto more = store.append({&b});
    EXPECT_EQ(more[0].segment, at[0].segment);
    EXPECT_EQ(more[0].offset, at[1].offset + 16 + int64_t(b.size()));
    {
      std::fstream f(store.segment_path(at[1].segment), std::ios::in | std::ios::out | std::ios::binary);
      f.seekp(at[1].offset + 16 + 3);
      f.put('X');
    }
    const auto got = store.read(at[1]);
    EXPECT_FALSE(got.bytes);
    EXPECT_NE(got.error.find("checksum error (XXH3-64 mismatch)"), std::string::npos) << got.error;
    EXPECT_EQ(store.read(at[0]).bytes.value_or("?"), a);
    // A batch whose rows were not committed is taken back: the segment is cut to where it was.
    store.undo_last_append();
    EXPECT_EQ(int64_t(fs::file_size(store.segment_path(at[0].segment))), more[0].offset);
  }
  fs::remove_all(root);
}

TEST_F(JobStoreTest, SchemaVersionOneIsRefusedWithTheReason) {
  { JobStore store(dir); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "tessera.db").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE schema_version SET version=1", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    JobStore store(dir);
    FAIL() << "schema version 1 was accepted";
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 1 (a file per tile"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("does not migrate"), std::string::npos) << e.what();
  }
}

TEST_F(JobStoreTest, SchemaVersionTwoIsMigratedKeepingItsJobs) {
  {
    JobStore store(dir);
    store.load();
    store.job_submitted(job("j1", 1));
    ASSERT_EQ(store.barrier().get(), "");
  }
  // Make it a version-2 database: the same tables without jobs.owner (and what versions 4 and 5
  // added: job_summaries, jobs.output); the migrations run 2 -> 3 -> 4 -> 5.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "tessera.db").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "ALTER TABLE jobs DROP COLUMN output; ALTER TABLE jobs DROP COLUMN owner; "
                         "DROP TABLE blocklist; DROP TABLE job_summaries; UPDATE schema_version SET version=2",
                         nullptr, nullptr, nullptr),
            SQLITE_OK)
      << sqlite3_errmsg(db);
  sqlite3_close(db);
  {
    JobStore store(dir);
    JobStore::Loaded l = store.load();
    ASSERT_EQ(l.jobs.size(), 1u);
    EXPECT_EQ(l.jobs[0].id, "j1");
    EXPECT_EQ(l.jobs[0].spec.owner, "");  // version 2 stored none: the job counts for no client
    EXPECT_EQ(l.jobs[0].spec.priority, 7);
    EXPECT_EQ(l.jobs[0].spec.output, "");  // nor an output
    JobSnapshot j2 = job("j2", 2);
    j2.spec.output = std::string("recorded\0output", 15);  // opaque bytes, NULs included
    store.job_submitted(j2);
    store.worker_blocklisted("j1", "bad");  // the migration created the blocklist table
    ASSERT_EQ(store.barrier().get(), "");
  }
  JobStore store(dir);
  JobStore::Loaded l = store.load();
  ASSERT_EQ(l.jobs.size(), 2u);
  EXPECT_EQ(l.jobs[0].blocklisted, std::vector<std::string>{"bad"});
  EXPECT_EQ(l.jobs[1].spec.owner, "ipv4:127.0.0.1");
  EXPECT_EQ(l.jobs[1].spec.output, std::string("recorded\0output", 15));
  ASSERT_EQ(sqlite3_open((dir / "tessera.db").c_str(), &db), SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "SELECT version FROM schema_version", -1, &st, nullptr);
  ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(st, 0), JobStore::kSchemaVersion);
  sqlite3_finalize(st);
  sqlite3_close(db);
}

TEST_F(JobStoreTest, BlocklistsSurviveARestartAndEviction) {
  {
    JobStore store(dir);
    store.load();
    store.job_submitted(job("j1", 1));
    store.job_submitted(job("j2", 2));
    store.worker_blocklisted("j1", "liar-b");
    store.worker_blocklisted("j1", "liar-a");
    store.worker_blocklisted("j1", "liar-a");  // twice: stored once
    ASSERT_EQ(store.barrier().get(), "");
  }
  {
    JobStore store(dir);
    JobStore::Loaded l = store.load();
    ASSERT_EQ(l.jobs.size(), 2u);
    EXPECT_EQ(l.jobs[0].blocklisted, (std::vector<std::string>{"liar-a", "liar-b"}));
    EXPECT_TRUE(l.jobs[1].blocklisted.empty());
    store.job_evicted("j1");
    ASSERT_EQ(store.barrier().get(), "");
    // An evicted job's status (read from SQLite) still names its blocklisted workers.
    const auto s = store.read_job("j1");
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->blocklisted, (std::vector<std::string>{"liar-a", "liar-b"}));
  }
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

// An evicted job's tile, acknowledged-frame and lease rows are shed once its eviction is
// committed; its status reads the same from its summary, before and after a restart. A job with
// more rows than a chunk is shed over several transactions.
TEST_F(JobStoreTest, EvictedJobsShedTheirRowsAndAnswerTheSame) {
  JobSnapshot big = job("big", 2);
  big.spec.width = 400;
  big.spec.height = 200;
  big.spec.tile_size = 4;  // 5,000 tiles a frame: two frames are more than a chunk
  std::tuple<JobState, int64_t, std::vector<int>, std::vector<int>> small_before, big_before;
  {
    JobStore store(dir);
    store.load();
    JobSnapshot small = job("small", 1);
    store.job_submitted(small);
    store.job_submitted(big);
    for (int t = 0; t < 6; ++t) store.tile_done({"small", 5, t}, out("s5t" + std::to_string(t), 1));
    store.tile_done({"small", 6, 0}, out("s6t0", 1));
    for (int f = 5; f <= 6; ++f) {
      for (int t = 0; t < 5000; ++t) store.tile_done({"big", f, t}, out("b", 1));
    }
    store.frame_acknowledged("small", 5, 6);
    store.frame_acknowledged("big", 6, 5000);
    store.lease_issued(lease(7, {"small", 6, 1}), "w1");
    small.state = big.state = JobState::kCancelled;
    small.ended = big.ended = Clock::now();
    store.job_updated(small);
    store.job_updated(big);
    ASSERT_EQ(store.barrier().get(), "");
    small_before = status(*store.read_job("small"));
    big_before = status(*store.read_job("big"));
    EXPECT_EQ(small_before,
              std::make_tuple(JobState::kCancelled, int64_t(7), std::vector<int>{5}, std::vector<int>{5}));
    EXPECT_EQ(std::get<1>(big_before), 10000);
    const auto start = std::chrono::steady_clock::now();
    store.job_evicted("small");
    store.job_evicted("big");
    ASSERT_EQ(store.barrier().get(), "");
    ASSERT_TRUE(shed(store));
    std::printf("evicted and shed 10,007 tile rows in %.0f ms (timing only, not checked)\n",
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    for (const char* table : {"tiles", "acked_frames", "leases"}) {
      EXPECT_EQ(rows_of(table, "small"), 0) << table;
      EXPECT_EQ(rows_of(table, "big"), 0) << table;
    }
    EXPECT_EQ(rows("SELECT count(*) FROM jobs")[0][0], 2);
    EXPECT_EQ(status(*store.read_job("small")), small_before);
    EXPECT_EQ(status(*store.read_job("big")), big_before);
  }
  JobStore store(dir);
  EXPECT_TRUE(store.load().jobs.empty());
  EXPECT_EQ(store.stats().jobs_to_shed, 0u);
  EXPECT_EQ(status(*store.read_job("small")), small_before);
  EXPECT_EQ(status(*store.read_job("big")), big_before);
}

// kill -9 between two chunks leaves a summary and some rows: the job answers from its summary (not
// from the rows left), is not loaded, and its last rows are shed after the next start. A database
// of the previous schema (rows of evicted jobs and no summaries) is shed the same way.
TEST_F(JobStoreTest, AJobHalfShedByACrashAnswersFromItsSummaryAndIsShedAtStart) {
  {
    JobStore store(dir);
    store.load();
    JobSnapshot s = job("j1", 1);
    store.job_submitted(s);
    for (int f = 5; f <= 6; ++f) {
      for (int t = 0; t < 6; ++t) store.tile_done({"j1", f, t}, out("x", 1));
    }
    store.frame_acknowledged("j1", 5, 6);
    store.frame_acknowledged("j1", 6, 6);
    s.state = JobState::kDone;
    s.ended = Clock::now();
    store.job_updated(s);
    ASSERT_EQ(store.barrier().get(), "");
  }
  // What the first chunk's transaction commits, and no more: the job evicted, its summary, its
  // first frame's rows gone.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir / "tessera.db").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "BEGIN; UPDATE jobs SET resident=0 WHERE id='j1'; INSERT INTO job_summaries VALUES"
                         "('j1', 12, '5-6', '5-6'); DELETE FROM tiles WHERE job='j1' AND frame=5; COMMIT",
                         nullptr, nullptr, nullptr),
            SQLITE_OK)
      << sqlite3_errmsg(db);
  sqlite3_close(db);
  ASSERT_EQ(rows_of("tiles", "j1"), 6);
  JobStore store(dir);
  EXPECT_TRUE(store.load().jobs.empty());
  const auto answer = std::make_tuple(JobState::kDone, int64_t(12), std::vector<int>{5, 6}, std::vector<int>{5, 6});
  EXPECT_EQ(status(*store.read_job("j1")), answer);
  ASSERT_TRUE(shed(store));
  EXPECT_EQ(rows_of("tiles", "j1"), 0);
  EXPECT_EQ(rows_of("acked_frames", "j1"), 0);
  EXPECT_EQ(status(*store.read_job("j1")), answer);
}

TEST(JobSummary, FramesRoundTripAsRanges) {
  for (const std::vector<int>& frames :
       {std::vector<int>{}, {0}, {3, 4, 5}, {0, 2, 4}, {1, 2, 3, 7, 9, 10}, {9999}}) {
    EXPECT_EQ(frames_from_ranges(frames_to_ranges(frames)), frames) << frames_to_ranges(frames);
  }
  EXPECT_EQ(frames_to_ranges({1, 2, 3, 7, 9, 10}), "1-3,7,9-10");
  EXPECT_THROW(frames_from_ranges("3-1"), std::runtime_error);
  EXPECT_THROW(frames_from_ranges("x"), std::runtime_error);
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

// Not a test of time (nothing is asserted about it): prints how many tiles/s the writer makes
// durable, the number docs/reliability.md quotes. Each tile is a lease issued + ended + a 4 KiB
// tile done, as the coordinator queues them. TESSERA_STORE_BENCH_TILES overrides the count.
// The commit window: every write queued while the writer waits joins one batch (one segment, one
// fdatasync, one commit), and a barrier ends the window at once. The window here is an hour: a
// barrier that waited it out would fail the wait_for below instead of passing after an hour.
TEST_F(JobStoreTest, CommitWindowGathersWritesIntoOneBatchAndABarrierEndsIt) {
  JobStore store(dir, std::chrono::hours(1));
  store.load();
  store.job_submitted(job("j1", 1));
  auto first = store.barrier();
  ASSERT_EQ(first.wait_for(std::chrono::seconds(120)), std::future_status::ready);
  ASSERT_EQ(first.get(), "");
  const JobStore::Stats before = store.stats();
  EXPECT_EQ(before.batches, 1);
  for (int t = 0; t < 6; ++t) {
    const Lease l = lease(LeaseId(t + 1), {"j1", 5, t});
    store.lease_issued(l, "w1");
    store.lease_ended(l.id);
    store.tile_done(l.tile, out("f5t" + std::to_string(t), 10));
  }
  auto second = store.barrier();
  ASSERT_EQ(second.wait_for(std::chrono::seconds(120)), std::future_status::ready);
  ASSERT_EQ(second.get(), "");
  const JobStore::Stats after = store.stats();
  EXPECT_EQ(after.batches, before.batches + 1);
  EXPECT_EQ(after.ops - before.ops, 6 * 3);       // the writes (a barrier is not counted)
  EXPECT_EQ(segment_files().size(), 1u);          // all six tiles in one segment
}

// Closing the store does not wait out the window: what is queued is written at once, and reads
// back. (An hour's window that the destructor waited for would time the test out.)
TEST_F(JobStoreTest, ClosingWritesWhatItsWindowHoldsAtOnce) {
  {
    JobStore store(dir, std::chrono::hours(1));
    store.load();
    store.job_submitted(job("j1", 1));
    store.tile_done({"j1", 6, 4}, out("f6t4", 7));
  }
  JobStore store(dir);
  JobStore::Loaded l = store.load();
  ASSERT_EQ(l.jobs.size(), 1u);
  ASSERT_EQ(l.jobs[0].done.size(), 1u);
  ASSERT_NE(l.jobs[0].done[0].output.payload, nullptr);
  EXPECT_EQ(*l.jobs[0].done[0].output.payload, "f6t4");
}

TEST_F(JobStoreTest, ThroughputMicroBenchmark) {
  int n = 2000;  // small for CI; TESSERA_STORE_BENCH_TILES=20032 for the documented numbers
  if (const char* e = std::getenv("TESSERA_STORE_BENCH_TILES")) n = std::max(1, std::atoi(e));
  JobStore store(dir);
  store.load();
  JobSnapshot s = job("bench", 1);
  s.spec.first_frame = 0;
  s.spec.last_frame = (n + 5) / 6 - 1;
  store.job_submitted(s);
  ASSERT_EQ(store.barrier().get(), "");
  const std::string pixels(4096, 'p');
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < n; ++i) {
    const Lease l = lease(LeaseId(i + 1), {"bench", i / 6, i % 6});
    store.lease_issued(l, "w");
    store.lease_ended(l.id);
    store.tile_done(l.tile, out(pixels, 1));
  }
  const auto t1 = std::chrono::steady_clock::now();
  ASSERT_EQ(store.barrier().get(), "");
  const auto t2 = std::chrono::steady_clock::now();
  const double enqueue = std::chrono::duration<double>(t1 - t0).count();
  const double total = std::chrono::duration<double>(t2 - t0).count();
  const auto st = store.stats();
  std::printf("[ bench    ] %d tiles of 4 KiB: enqueue %.2f us/tile, durable after %.3f s = %.0f tiles/s, %lld batches\n",
              n, 1e6 * enqueue / n, total, n / total, static_cast<long long>(st.batches));
  // Everything written reads back (the benchmark measured real writes).
  JobStore again(dir);
  JobStore::Loaded l = again.load();
  ASSERT_EQ(l.jobs.size(), 1u);
  EXPECT_EQ(int(l.jobs[0].done.size()), n);
}

}  // namespace
}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// Persistence with real processes: finished tiles survive kill -9 of the coordinator and come
// back bit-identical from disk; a corrupt database, an unwritable data directory and a full disk
// give clear errors instead of silent data loss.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/mount.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "farm_harness.h"
#include "image/exr_io.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");

void expect_frames_identical(const fs::path& dir) {
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(dir / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }
}

// Starts tessera-server on `data` and returns (exit code, output) when it exits by itself.
CliResult server_refusing(Farm& farm, const fs::path& data) {
  Process p({bin("tessera-server").string(), "--listen", "127.0.0.1:0", "--data-dir", data.string()},
            farm.dir() / "refused.log");
  CliResult r;
  r.code = p.wait(20s);
  r.output = p.log();
  return r;
}

TEST(FarmPersistence, FinishedTilesSurviveKill9AndComeBackFromDisk) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1");
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 72));
  farm.workers().clear();  // no worker: every pixel below must come from the coordinator's disk
  // A result is durable once its batch commits. SubmitJob answers only after everything queued
  // before it is committed, so a second submit is the barrier that makes the first job's tiles
  // durable; then kill -9 without warning.
  CliResult barrier =
      farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(barrier.code, 0) << barrier.output;
  farm.restart_server();
  std::string state;
  EXPECT_EQ(farm.tiles_done(job, &state), 72);
  EXPECT_EQ(state, "done");
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()});
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  expect_frames_identical(out);
  // Every frame acknowledged: the job left memory and its tile files are gone, but its status
  // is still answered (from SQLite), across another restart too.
  EXPECT_NE(farm.server().log().find("job " + job + " left memory"), std::string::npos) << farm.server().log();
  // (Another submit as a barrier: the eviction's batch, file deletions included, is done.)
  ASSERT_EQ(farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"}).code, 0);
  // The only finished tiles were this job's, all acknowledged: no segment file may remain.
  int segments = 0;
  for (const auto& e : fs::directory_iterator(farm.data_dir() / "tiles")) segments += e.path().extension() == ".seg";
  EXPECT_EQ(segments, 0);
  farm.restart_server();
  EXPECT_EQ(farm.tiles_done(job, &state), 72);
  EXPECT_EQ(state, "done");
  CliResult list = farm.cli({"status", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(list.code, 0) << list.output;
  // Only the two barrier jobs (queued, no worker) are in memory: the evicted job is not reloaded.
  auto resident = nlohmann::json::parse(list.output);
  EXPECT_EQ(resident.size(), 2u) << list.output;
  for (const auto& j : resident) EXPECT_NE(j.at("job_id"), job) << "evicted jobs must not be loaded into memory";
}

TEST(FarmPersistence, CorruptDatabaseStopsTheCoordinatorNamingTheFile) {
  Farm farm;
  farm.start_server();
  farm.server().signal(SIGTERM);
  ASSERT_EQ(farm.server().wait(20s), 0);
  const fs::path db = farm.data_dir() / "tessera.db";
  ASSERT_TRUE(fs::exists(db));
  fs::remove(farm.data_dir() / "tessera.db-wal");
  fs::remove(farm.data_dir() / "tessera.db-shm");
  {
    std::ofstream f(db, std::ios::binary | std::ios::trunc);
    for (int i = 0; i < 4096; ++i) f << "garbage!";
  }
  CliResult r = server_refusing(farm, farm.data_dir());
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find(db.string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("corrupt"), std::string::npos) << r.output;
}

TEST(FarmPersistence, UnwritableDataDirStopsTheCoordinator) {
  Farm farm;
  {
    std::ofstream(farm.dir() / "a-file") << "x";
  }
  CliResult r = server_refusing(farm, farm.dir() / "a-file" / "data");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find((farm.dir() / "a-file" / "data").string()), std::string::npos) << r.output;
  // A read-only file system (root ignores permission bits, so mount one when we may).
  const fs::path ro = farm.dir() / "ro";
  fs::create_directories(ro);
  if (mount("tmpfs", ro.c_str(), "tmpfs", MS_RDONLY, "size=1m") != 0) {
    std::printf("[skip] read-only data dir: cannot mount a tmpfs here (%s)\n", std::strerror(errno));
    return;
  }
  CliResult r2 = server_refusing(farm, ro);
  umount(ro.c_str());
  EXPECT_EQ(r2.code, 1) << r2.output;
  EXPECT_NE(r2.output.find(ro.string()), std::string::npos) << r2.output;
  EXPECT_NE(r2.output.find("Read-only file system"), std::string::npos) << r2.output;
}

TEST(FarmPersistence, FullDiskRefusesNewJobsAndRecovers) {
  Farm farm;
  const fs::path small = farm.dir() / "small";
  fs::create_directories(small);
  if (mount("tmpfs", small.c_str(), "tmpfs", 0, "size=16m") != 0) {
    GTEST_SKIP() << "cannot mount a small tmpfs here (" << std::strerror(errno) << "): full-disk test skipped";
  }
  struct Unmount {
    fs::path p;
    ~Unmount() { umount2(p.c_str(), MNT_DETACH); }
  } unmount{small};
  // The coordinator's data on the small disk (the harness's --data-dir is replaced by the last one).
  farm.start_server({"--data-dir", (small / "data").string()});
  CliResult a = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(a.code, 0) << a.output;
  const std::string job = job_id_from(a.output);
  // Fill the disk.
  {
    std::ofstream fill(small / "filler", std::ios::binary);
    const std::string mb(1 << 20, 'x');
    for (int i = 0; i < 32 && fill; ++i) fill << mb;
  }
  // Tiles can no longer be stored: the coordinator says so, loudly.
  farm.start_worker("w1");
  for (int i = 0; i < 100 && farm.server().log().find("cannot persist") == std::string::npos; ++i) {
    std::this_thread::sleep_for(100ms);
  }
  // SQLite's SQLITE_FULL or the tile file's ENOSPC, whichever write came first.
  const std::string full_log = farm.server().log();
  EXPECT_TRUE(full_log.find("database or disk is full") != std::string::npos ||
              full_log.find("No space left on device") != std::string::npos)
      << full_log;
  CliResult b = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  EXPECT_NE(b.code, 0) << b.output;
  EXPECT_NE(b.output.find("no new jobs"), std::string::npos) << b.output;
  // Space again: the queued writes go through, the job completes, new jobs are accepted.
  fs::remove(small / "filler");
  ASSERT_TRUE(farm.wait_tiles_done(job, 72, 60s));
  for (int i = 0; i < 100 && farm.server().log().find("storage recovered") == std::string::npos; ++i) {
    std::this_thread::sleep_for(100ms);
  }
  CliResult c = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  EXPECT_EQ(c.code, 0) << c.output << farm.server().log();
  // And what was reported done is on disk: restart and read it back.
  farm.restart_server();
  std::string state;
  EXPECT_EQ(farm.tiles_done(job, &state), 72);
  const fs::path out = farm.dir() / "out";
  farm.workers().clear();
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()});
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  expect_frames_identical(out);
}

// The rows the coordinator's database holds of a job, read with SQLite beside the running
// coordinator (WAL: a reader never blocks its writer); -1 each when the file cannot be read.
struct JobRows {
  int64_t jobs = -1, tiles = -1, acked_frames = -1, leases = -1;
  bool operator==(const JobRows&) const = default;
};

JobRows rows_of(const fs::path& db_path, const std::string& job) {
  JobRows rows;
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    const auto count = [&](const char* sql) -> int64_t {
      sqlite3_stmt* st = nullptr;
      int64_t n = -1;
      if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, job.c_str(), -1, SQLITE_TRANSIENT);
        if (sqlite3_step(st) == SQLITE_ROW) n = sqlite3_column_int64(st, 0);
      }
      sqlite3_finalize(st);
      return n;
    };
    rows = {count("SELECT count(*) FROM jobs WHERE id=?1"), count("SELECT count(*) FROM tiles WHERE job=?1"),
            count("SELECT count(*) FROM acked_frames WHERE job=?1"), count("SELECT count(*) FROM leases WHERE job=?1")};
  }
  sqlite3_close(db);
  return rows;
}

// What `tessera status JOB --json` says of a job: the fields an evicted job answers from the
// database.
nlohmann::json status_of(Farm& farm, const std::string& job) {
  const CliResult r = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  EXPECT_EQ(r.code, 0) << r.output;
  if (r.code != 0) return {};
  const nlohmann::json j = nlohmann::json::parse(r.output);
  return {{"state", j.at("state")}, {"tiles_done", j.at("tiles_done")}, {"tiles_total", j.at("tiles_total")},
          {"frames_done", j.at("frames_done")}, {"frames_acknowledged", j.at("frames_acknowledged")}};
}

// Jobs delivered to their client leave memory, and now the database sheds their rows too: a tile
// row per finished tile and a row per acknowledged frame used to stay forever (28,800 tile rows
// after three small jobs), the database only grew. What is left of a job is its own row (and a
// summary of what it did), so `tessera status JOB` answers as before, across a restart too.
TEST(FarmPersistence, DeliveredJobsShedTheirTileRowsAndStillAnswerTheirStatus) {
  Farm farm;
  farm.start_server();
  farm.start_worker("w1");
  std::vector<std::string> jobs;
  for (int i = 0; i < 3; ++i) {
    const fs::path out = farm.dir() / ("out" + std::to_string(i));
    const CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "-o",
                                  (out / "frame_####.exr").string()});
    ASSERT_EQ(r.code, 0) << r.output;
    jobs.push_back(job_id_from(r.output));
    expect_frames_identical(out);
  }
  const nlohmann::json delivered = {{"state", "done"},
                                    {"tiles_done", 72},
                                    {"tiles_total", 72},
                                    {"frames_done", {0, 1, 2}},
                                    {"frames_acknowledged", {0, 1, 2}}};
  const fs::path db = farm.data_dir() / "tessera.db";
  const JobRows summary_only{1, 0, 0, 0};
  for (const std::string& job : jobs) {
    SCOPED_TRACE("job " + job);
    EXPECT_NE(farm.server().log().find("job " + job + " left memory"), std::string::npos) << farm.server().log();
    // Shed by the store's writer after the eviction is committed: within a moment, not at once.
    JobRows rows = rows_of(db, job);
    for (int i = 0; i < 400 && !(rows == summary_only); ++i) {
      std::this_thread::sleep_for(50ms);
      rows = rows_of(db, job);
    }
    EXPECT_EQ(rows.jobs, 1);
    EXPECT_EQ(rows.tiles, 0);
    EXPECT_EQ(rows.acked_frames, 0);
    EXPECT_EQ(rows.leases, 0);
    EXPECT_EQ(status_of(farm, job), delivered);
  }
  // A restart reads the shed database: the jobs still answer, none is loaded, and a new job runs.
  farm.restart_server();
  for (const std::string& job : jobs) EXPECT_EQ(status_of(farm, job), delivered) << job;
  const CliResult list = farm.cli({"status", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(list.code, 0) << list.output;
  EXPECT_TRUE(nlohmann::json::parse(list.output).empty()) << list.output;
  const fs::path out = farm.dir() / "after";
  const CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "-o",
                                (out / "frame_####.exr").string()});
  ASSERT_EQ(r.code, 0) << r.output << farm.server_logs();
  expect_frames_identical(out);
}

// A data directory written by tessera-server 1bf2db9 (tests/data/datadir-previous/README.md says
// how) serves on under this release: its jobs answer with their states, the done job's frames
// are delivered from its stored tiles with no worker connected (a tile this release could not
// read back would be rendered again, and nothing would render it: watch would not finish), and
// its queued job renders from the stored bundle once a worker comes.
TEST(FarmPersistence, ServesADataDirWrittenByThePreviousRelease) {
  Farm farm;
  fs::copy(source("tests/data/datadir-previous/data"), farm.data_dir(), fs::copy_options::recursive);
  // The recorded jobs ended on the day the data dir was written: with the default retention (24 h)
  // their unacknowledged frames would leave memory a day later and this test would fail from then
  // on. The longest retention keeps them for ten years, as a coordinator restarted soon would.
  farm.start_server({"--retention-hours", "87600"});
  const std::string a = "274c9bcc6306", b = "3c6f8f7123b3", c = "c44b713d704a", d = "5f56229c862f";
  CliResult list = farm.cli({"status", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(list.code, 0) << list.output;
  std::map<std::string, std::pair<std::string, int>> jobs;  // id -> (state, tiles done)
  for (const auto& j : nlohmann::json::parse(list.output)) jobs[j.at("job_id")] = {j.at("state"), j.at("tiles_done")};
  using Jobs = decltype(jobs);
  EXPECT_EQ(jobs, (Jobs{{a, {"done", 30}}, {c, {"queued", 0}}, {d, {"cancelled", 0}}})) << list.output;
  std::string state;
  EXPECT_EQ(farm.tiles_done(b, &state), 15);  // fetched and evicted: answered from the database
  EXPECT_EQ(state, "done");
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", a, "--coordinator", farm.address(), "-o", (out / "a_####.exr").string()}, 60s);
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  for (int f = 0; f < 2; ++f) {
    const ImageRGB img = read_exr((out / ("a_000" + std::to_string(f) + ".exr")).string());
    ASSERT_EQ(img.width, 72);
    ASSERT_EQ(img.height, 40);
    // Every 16-pixel tile holds rendered pixels (a tile left out would stay black).
    for (int ty = 0; ty < 3; ++ty) {
      for (int tx = 0; tx < 5; ++tx) {
        float sum = 0;
        for (int y = ty * 16; y < std::min(40, ty * 16 + 16); ++y) {
          for (int x = tx * 16; x < std::min(72, tx * 16 + 16); ++x) {
            for (int ch = 0; ch < 3; ++ch) sum += img.rgb[size_t(3 * (y * 72 + x) + ch)];
          }
        }
        EXPECT_GT(sum, 0.f) << "frame " << f << " tile " << ty * 5 + tx;
      }
    }
  }
  farm.start_worker("w1");
  CliResult wc = farm.cli({"watch", c, "--coordinator", farm.address(), "-o", (out / "c_####.exr").string()});
  ASSERT_EQ(wc.code, 0) << wc.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) EXPECT_TRUE(fs::exists(out / ("c_000" + std::to_string(f) + ".exr"))) << f;
}

}  // namespace
}  // namespace tessera::farmtest

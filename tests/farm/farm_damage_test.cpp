// SPDX-License-Identifier: Apache-2.0
// Damaged storage with real processes: the coordinator is stopped, its
// files under --data-dir are damaged the way a disk, an operator or a bad restore would, and it
// is started again. It must never report success over a wrong or missing frame: a damaged or
// misplaced tile is rendered again (its job runs again), and an emptied database does not make
// it delete the farm's finished tiles.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <map>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 96x64, 3 frames

// Segment files under the data dir, by number.
std::map<int64_t, fs::path> segments(const Farm& farm) {
  std::map<int64_t, fs::path> out;
  for (const auto& e : fs::directory_iterator(farm.data_dir() / "tiles")) {
    if (e.path().extension() == ".seg") out[std::stoll(e.path().stem().string())] = e.path();
  }
  return out;
}

// Renders the 3-frame scene as a detached job with one worker, then stops the coordinator
// cleanly (SIGTERM: everything queued is committed), with no worker left. Returns the job id.
std::string render_and_stop(Farm& farm, const std::string& tile, int delay_ms) {
  farm.start_server();
  farm.start_worker("w1", 1, delay_ms);
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", tile, "--detach"});
  EXPECT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  std::string state;
  for (int i = 0; i < 1200 && state != "done"; ++i) {
    farm.tiles_done(job, &state);
    if (state != "done") std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(state, "done") << farm.server().log();
  farm.workers().clear();
  farm.server().signal(SIGTERM);
  EXPECT_EQ(farm.server().wait(30s), 0) << farm.server().log();
  return job;
}

// Starts the coordinator again with one worker and fetches every frame with `tessera watch -o`:
// it must exit 0 with all three frames on disk, bit-identical to `tessera render`.
void expect_watch_writes_every_frame(Farm& farm, const std::string& job) {
  farm.start_server(farm.server_extra());
  farm.start_worker("w2");
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()});
  EXPECT_EQ(w.code, 0) << w.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f << "\n" << w.output;
  }
}

TEST(FarmDamage, TruncatedTileOfADoneJobIsRenderedAgainAndEveryFrameWritten) {
  Farm farm;
  const std::string job = render_and_stop(farm, "16", 0);
  // Cut the newest segment short: its last record (a tile of the done job) is now torn.
  const auto segs = segments(farm);
  ASSERT_FALSE(segs.empty());
  const fs::path newest = segs.rbegin()->second;
  fs::resize_file(newest, fs::file_size(newest) - 100);
  expect_watch_writes_every_frame(farm, job);
  const std::string log = farm.server_logs();
  EXPECT_NE(log.find("will be rendered again"), std::string::npos) << log;
  EXPECT_NE(log.find(newest.string()), std::string::npos) << "the error names the damaged file\n" << log;
}

// The records of a segment: offset -> total size (header and payload). A record is a 16-byte
// header (magic "TRX3", payload length, XXH3-64; little-endian) then the payload
// (server/tile_store.cpp).
std::map<int64_t, int64_t> records(const fs::path& segment) {
  std::ifstream f(segment, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::map<int64_t, int64_t> out;
  for (size_t off = 0; off + 16 <= bytes.size();) {
    uint32_t len = 0;
    for (int i = 0; i < 4; ++i) len |= uint32_t(uint8_t(bytes[off + 4 + size_t(i)])) << (8 * i);
    out[int64_t(off)] = 16 + int64_t(len);
    off += 16 + len;
  }
  return out;
}

TEST(FarmDamage, SwappedRecordsAreNotServedAsTheWrongFrame) {
  Farm farm;
  // One tile per frame: the three records have the same length, so a swap keeps every record
  // readable (length and checksum); only its identity betrays it.
  const std::string job = render_and_stop(farm, "96", 0);
  const auto segs = segments(farm);
  fs::path seg;
  int64_t a = -1, b = -1, size = 0;
  for (const auto& [n, path] : segs) {
    const auto recs = records(path);
    for (auto i = recs.begin(); i != recs.end() && a < 0; ++i) {
      for (auto j = std::next(i); j != recs.end(); ++j) {
        if (i->second == j->second) {
          seg = path;
          a = i->first;
          b = j->first;
          size = i->second;
          break;
        }
      }
    }
    if (a >= 0) break;
  }
  ASSERT_GE(a, 0) << "no two records of equal length in " << segs.size() << " segments";
  {
    std::fstream f(seg, std::ios::in | std::ios::out | std::ios::binary);
    std::string ra(size_t(size), '\0'), rb(size_t(size), '\0');
    f.seekg(a);
    f.read(ra.data(), size);
    f.seekg(b);
    f.read(rb.data(), size);
    f.seekp(a);
    f.write(rb.data(), size);
    f.seekp(b);
    f.write(ra.data(), size);
  }
  expect_watch_writes_every_frame(farm, job);
  const std::string log = farm.server_logs();
  EXPECT_NE(log.find("the record is not this tile: it is job " + job + " frame"), std::string::npos) << log;
}

TEST(FarmDamage, CorruptRecordIsReportedAsAChecksumError) {
  Farm farm;
  const std::string job = render_and_stop(farm, "16", 0);
  const auto segs = segments(farm);
  ASSERT_FALSE(segs.empty());
  const fs::path seg = segs.begin()->second;
  {
    // Flip a byte inside the first record's pixels (past its 16-byte header).
    std::fstream f(seg, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(200);
    char c = 0;
    f.read(&c, 1);
    c = char(c ^ 0x5a);
    f.seekp(200);
    f.write(&c, 1);
  }
  expect_watch_writes_every_frame(farm, job);
  const std::string log = farm.server_logs();
  EXPECT_NE(log.find(seg.string() + " at offset 0: checksum error"), std::string::npos) << log;
}

TEST(FarmDamage, EmptyDatabaseBesideTilesRefusesToStartAndDeletesNothing) {
  Farm farm;
  render_and_stop(farm, "16", 0);
  const size_t before = segments(farm).size();
  ASSERT_GT(before, 0u);
  const fs::path db = farm.data_dir() / "tessera.db";
  fs::resize_file(db, 0);
  fs::remove(farm.data_dir() / "tessera.db-wal");
  fs::remove(farm.data_dir() / "tessera.db-shm");
  Process p({bin("tessera-server").string(), "--listen", "127.0.0.1:0", "--data-dir", farm.data_dir().string()},
            farm.dir() / "refused.log");
  EXPECT_EQ(p.wait(20s), 1) << p.log();
  EXPECT_NE(p.log().find(db.string() + " is empty (0 bytes)"), std::string::npos) << p.log();
  EXPECT_EQ(segments(farm).size(), before) << "no tile file may be deleted";
  // A missing database beside tiles is refused the same way.
  fs::remove(db);
  Process q({bin("tessera-server").string(), "--listen", "127.0.0.1:0", "--data-dir", farm.data_dir().string()},
            farm.dir() / "refused-2.log");
  EXPECT_EQ(q.wait(20s), 1) << q.log();
  EXPECT_NE(q.log().find(db.string() + " is missing"), std::string::npos) << q.log();
  EXPECT_EQ(segments(farm).size(), before);
}

TEST(FarmDamage, EmptyDatabaseInAnOtherwiseEmptyDirectoryIsANewFarm) {
  Farm farm;
  fs::create_directories(farm.data_dir());
  std::ofstream(farm.data_dir() / "tessera.db").close();  // 0 bytes, nothing else
  farm.start_server();  // throws if it exits
  EXPECT_TRUE(farm.server().running());
}

TEST(FarmDamage, ClientRefusesAFrameWithAMissingTileAndSaysWhich) {
  // Whatever the coordinator says, the client checks: a frame reported done with a tile
  // missing is neither written nor acknowledged, and "done" is not success then.
  Farm farm;
  Process fake({"/usr/bin/python3", source("tests/farm/fake_coordinator.py").string(), source("proto").string(),
                farm.dir().string()},
               farm.dir() / "fake.log");
  std::string address;
  for (int i = 0; i < 800 && address.empty(); ++i) {
    const std::string log = fake.log();
    const auto at = log.find("listening on ");
    const auto eol = at == std::string::npos ? at : log.find('\n', at);
    if (eol != std::string::npos) {
      address = log.substr(at + 13, eol - at - 13);
    } else {
      ASSERT_TRUE(fake.running()) << log;
      std::this_thread::sleep_for(25ms);
    }
  }
  ASSERT_FALSE(address.empty()) << fake.log();
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", "liar", "--coordinator", address, "-o", (out / "f_####.exr").string()});
  EXPECT_EQ(w.code, 1) << w.output;
  EXPECT_NE(w.output.find("frame 0: tile 1 missing (1 of 2 received)"), std::string::npos) << w.output;
  EXPECT_FALSE(fs::exists(out / "f_0000.exr"));
  EXPECT_EQ(fake.log().find("ACK"), std::string::npos) << fake.log();
}

}  // namespace
}  // namespace tessera::farmtest

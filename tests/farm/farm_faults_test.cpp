// SPDX-License-Identifier: Apache-2.0
// Bad workers (tessera-worker --test-fault, testing only): every wrong result is refused with
// its precise reason in the coordinator's log, the worker is blocklisted for the job after
// --max-faults of them, the good worker finishes the job bit-identical; and a job that every
// worker fails on fails with a clear error instead of hanging; and daemons whose log reader goes
// away keep working.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");

// Polls `tessera workers` until `n` workers are registered (10 s at most).
void wait_for_workers(Farm& farm, size_t n) {
  for (int i = 0; i < 200; ++i) {
    CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
    if (w.code == 0 && nlohmann::json::parse(w.output).size() == n) return;
    std::this_thread::sleep_for(50ms);
  }
}

TEST(FarmFaults, BadResultsAreRefusedAndTheirWorkersBlocklisted) {
  Farm farm;
  farm.start_server({"--max-faults", "3"});
  // Four liars, one honest (slowed so the liars get tiles before the job ends).
  const std::vector<std::pair<std::string, std::string>> faults{
      {"nan", "is NaN"},
      {"wrong-size", "tile rgb has"},
      {"stale", "never issued by this coordinator"},
      {"no-scene", "worker cannot render: cannot load the scene"},
      {"negative-variance", "is negative (-1.000000)"},
      {"nan-seconds", "render time nan s is not a finite duration >= 0"}};
  for (const auto& [mode, reason] : faults) farm.start_worker("bad-" + mode, 1, 0, {"--test-fault", mode});
  farm.start_worker("good", 1, 20);
  wait_for_workers(farm, faults.size() + 1);  // the liars alone would fail the job
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (out / "frame_####.exr").string(), "--tile", "16"});
  ASSERT_EQ(r.code, 0) << r.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }
  const std::string log = farm.server_logs();
  const std::string job = job_id_from(r.output);
  for (const auto& [mode, reason] : faults) {
    const std::string name = "'bad-" + mode + "'";
    EXPECT_NE(log.find(name + ": refused result for job " + job), std::string::npos) << mode << "\n" << log;
    EXPECT_NE(log.find(reason), std::string::npos) << mode << "\n" << log;
    EXPECT_NE(log.find(name + " is blocklisted for job " + job + " after 3 faults"), std::string::npos)
        << mode << "\n" << log;
  }
  CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  // Evicted after the client acknowledged every frame: the status comes from SQLite, blocklist
  // included; the job is done with every tile exactly once.
  auto j = nlohmann::json::parse(st.output);
  EXPECT_EQ(j.at("state"), "done");
  EXPECT_EQ(j.at("tiles_done"), 72);
  EXPECT_EQ(j.at("blocklisted_workers").size(), faults.size()) << st.output;
  // Blocklisted workers rendered no accepted tile: all 72 came from the honest worker.
  CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(w.code, 0) << w.output;
  for (const auto& x : nlohmann::json::parse(w.output)) {
    if (x.at("name") == "good") {
      EXPECT_EQ(x.at("tiles_done").get<int>(), 72);
    } else {
      EXPECT_EQ(x.at("tiles_done").get<int>(), 0) << x.dump();
    }
  }
}

// Sum of the sizes of the coordinator's tile segments.
uintmax_t tile_bytes_on_disk(const Farm& farm) {
  uintmax_t bytes = 0;
  for (const auto& e : fs::directory_iterator(farm.data_dir() / "tiles")) bytes += e.file_size();
  return bytes;
}

// A worker that pads its (honest) results with unknown fields, 1 MiB a tile: the coordinator
// stores and forwards only the fields a tile has, so the padding costs neither disk nor memory
// nor a client that cannot receive it, and the frames are right.
TEST(FarmFaults, PaddedResultsAreStoredAndSentWithoutThePadding) {
  Farm farm;
  farm.start_server();
  farm.start_worker("padded", 1, 0, {"--test-fault", "padded"});
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 72)) << farm.server_logs();
  // A barrier (another submit answers once everything before it is stored): every tile is on disk.
  ASSERT_EQ(farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach"}).code, 0);
  // 72 tiles of 16x16 px: 14 bytes a pixel of pixel data and ~100 of identity each, ~270 KB. With
  // the padding it would be over 72 MiB.
  EXPECT_LT(tile_bytes_on_disk(farm), uintmax_t(1) << 20) << "the padding was stored";
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()});
  ASSERT_EQ(w.code, 0) << w.output << farm.server_logs();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }
}

// A worker's description of itself is bounded (its name goes into every tile it renders): one
// over the bound is refused at registration, naming the field and the bound, and never joins.
TEST(FarmFaults, OversizedRegistrationIsRefusedNamingTheField) {
  Farm farm;
  farm.start_server();
  Process long_named({bin("tessera-worker").string(), "--coordinator", farm.address(), "--name", std::string(1000, 'n'),
                      "--cache-dir", (farm.dir() / "cache-long").string()},
                     farm.dir() / "worker-long.log");
  farm.start_worker("fine");
  wait_for_workers(farm, 1);
  std::this_thread::sleep_for(500ms);  // time for the long-named one to have tried, and retried
  CliResult w = farm.cli({"workers", "--json", "--coordinator", farm.address()});
  ASSERT_EQ(w.code, 0) << w.output;
  const auto listed = nlohmann::json::parse(w.output);
  ASSERT_EQ(listed.size(), 1u) << w.output;
  EXPECT_EQ(listed[0].at("name"), "fine");
  const std::string log = farm.server_logs();
  EXPECT_NE(log.find("refused: register.name is 1000 bytes, at most 256"), std::string::npos) << log;
}

// Whether the coordinator's database holds (job, worker) in its blocklist within 10 s, read with
// SQLite beside the running coordinator (WAL: readers never block its writer).
bool eventually_stored(const fs::path& db_path, const std::string& job, const std::string& worker) {
  for (int i = 0; i < 400; ++i) {
    sqlite3* db = nullptr;
    bool found = false;
    if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
      sqlite3_stmt* st = nullptr;
      if (sqlite3_prepare_v2(db, "SELECT 1 FROM blocklist WHERE job=?1 AND worker=?2", -1, &st, nullptr) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, job.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_text(st, 2, worker.c_str(), -1, SQLITE_TRANSIENT);
        found = sqlite3_step(st) == SQLITE_ROW;
      }
      sqlite3_finalize(st);
    }
    sqlite3_close(db);
    if (found) return true;
    std::this_thread::sleep_for(25ms);
  }
  return false;
}

TEST(FarmFaults, BlocklistSurvivesACoordinatorRestart) {
  Farm farm;
  farm.start_server({"--max-faults", "2"});
  farm.start_worker("liar", 1, 0, {"--test-fault", "nan"});
  farm.start_worker("honest", 1, 150);  // slow: the job is still running at the restart
  // Both registered first: were the liar alone when it is blocklisted, the job would fail
  // ("every connected worker is blocklisted") before the honest worker joined.
  wait_for_workers(farm, 2);
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--detach", "--tile", "16"});
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string job = job_id_from(r.output);
  const std::string blocked = "'liar' is blocklisted for job " + job;
  for (int i = 0; i < 400 && farm.server().log().find(blocked) == std::string::npos; ++i) std::this_thread::sleep_for(25ms);
  ASSERT_NE(farm.server().log().find(blocked), std::string::npos) << farm.server_logs();
  // The store commits in groups on its own thread (server/job_store.h), a few milliseconds after
  // the log line: kill -9 in between would lose the entry (the liar would then fault twice more
  // and be blocklisted again). What this test asserts is that a stored blocklist is loaded after
  // a crash, so it crashes the coordinator once the row is in the database file.
  ASSERT_TRUE(eventually_stored(farm.data_dir() / "tessera.db", job, "liar")) << farm.server_logs();
  farm.restart_server();
  // Straight from the database: the restarted coordinator already refuses the liar this job.
  CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  auto j = nlohmann::json::parse(st.output);
  ASSERT_TRUE(j.at("state") == "running" || j.at("state") == "queued") << st.output << farm.server_logs();
  EXPECT_EQ(j.at("blocklisted_workers"), nlohmann::json::array({"liar"})) << st.output;
  ASSERT_TRUE(farm.wait_tiles_done(job, 72, 120s)) << farm.server_logs();
  // The liar reconnected to the new coordinator and got no tile of the job: no refused result
  // in the new log (without the stored blocklist it would fault twice more).
  const std::string log = farm.server().log();
  EXPECT_EQ(log.find("'liar': refused result for job " + job), std::string::npos) << log;
  EXPECT_EQ(farm.tiles_done(job), 72);
}

TEST(FarmFaults, JobFailsClearlyWhenEveryWorkerIsBlocklisted) {
  Farm farm;
  farm.start_server({"--max-faults", "2"});
  farm.start_worker("broken-1", 1, 0, {"--test-fault", "no-scene"});
  farm.start_worker("broken-2", 1, 0, {"--test-fault", "nan"});
  // Both must be registered before they run out of tiles, or the job would wait for a third.
  wait_for_workers(farm, 2);
  CliResult r = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "-o",
                          (farm.dir() / "out" / "f_####.exr").string(), "--tile", "16"});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("failed: every connected worker (2) is blocklisted for this job after 2 faults each"),
            std::string::npos)
      << r.output << farm.server_logs();
  const std::string job = job_id_from(r.output);
  CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  auto j = nlohmann::json::parse(st.output);
  EXPECT_EQ(j.at("state"), "failed");
  EXPECT_EQ(j.at("blocklisted_workers").size(), 2u) << st.output;
}

// A daemon's output read through a pipe (`tessera-server | tee log`, a log shipper) whose reader
// goes away: every later log line is a write to a pipe without a reader, which raises SIGPIPE,
// and SIGPIPE's default action ends the process. The coordinator and the worker lose the log
// lines, not the job: both keep working, the frames are right and the worker leaves cleanly on
// SIGTERM. (The builds before the guard in worker/main.cpp die at the first line after the reader
// left: the worker on its SIGTERM line, the coordinator on its next debug line.)
TEST(FarmFaults, ALogReaderThatGoesAwayEndsNeitherCoordinatorNorWorker) {
  Farm farm;
  // Opens a FIFO for reading (non-blocking, so a child can open it to write) and returns what
  // arrives until `until` matches, or 20 s pass; the caller closes the descriptor.
  const auto fifo_reader = [&](const std::string& name) {
    const fs::path p = farm.dir() / name;
    EXPECT_EQ(mkfifo(p.c_str(), 0600), 0) << p;
    return std::pair{p, open(p.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};  // not the child's
  };
  const auto read_until = [](int fd, const std::regex& until) {
    std::string text;
    const auto end = std::chrono::steady_clock::now() + 20s;
    std::smatch m;
    while (!std::regex_search(text, m, until) && std::chrono::steady_clock::now() < end) {
      pollfd p{fd, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      char buf[4096];
      const ssize_t n = read(fd, buf, sizeof buf);
      if (n > 0) text.append(buf, size_t(n));
    }
    return std::regex_search(text, m, until) ? m[1].str() : std::string();
  };

  auto [server_fifo, server_out] = fifo_reader("server.fifo");
  ASSERT_GE(server_out, 0);
  auto server = std::make_unique<Process>(
      std::vector<std::string>{bin("tessera-server"), "--listen", "127.0.0.1:0", "--data-dir",
                               farm.data_dir().string(), "--log-level", "debug"},
      server_fifo);
  const std::string address = read_until(server_out, std::regex("listening on (127\\.0\\.0\\.1:[0-9]+)"));
  ASSERT_FALSE(address.empty()) << "no 'listening on' line from the coordinator";
  close(server_out);  // the reader goes away

  auto [worker_fifo, worker_out] = fifo_reader("worker.fifo");
  ASSERT_GE(worker_out, 0);
  Process worker({bin("tessera-worker"), "--coordinator", address, "--threads", "1", "--name", "w1", "--cache-dir",
                  (farm.dir() / "cache").string(), "--log-level", "info"},
                 worker_fifo);
  ASSERT_FALSE(read_until(worker_out, std::regex("(connected to)")).empty()) << "the worker did not connect";
  close(worker_out);

  // The coordinator logs at debug level for every message it takes: a job is dozens of lines.
  const fs::path out = farm.dir() / "out";
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", address, "--tile", "16", "-o",
                          (out / "frame_####.exr").string()},
                         60s);
  ASSERT_EQ(s.code, 0) << s.output << "\nthe worker " << (worker.running() ? "runs" : "died");
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }
  EXPECT_TRUE(server->running()) << "the coordinator died";
  EXPECT_EQ(farm.cli({"status", "--coordinator", address}).code, 0);
  // SIGTERM: the worker logs that it finishes its tiles and leaves, then leaves with status 0.
  worker.signal(SIGTERM);
  EXPECT_EQ(worker.wait(20s), 0) << "the worker did not leave cleanly (128 + 13: it died of SIGPIPE)";
  EXPECT_TRUE(server->running()) << "the coordinator died";
}

}  // namespace
}  // namespace tessera::farmtest

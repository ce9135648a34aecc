// SPDX-License-Identifier: Apache-2.0
// Exhaustion with real processes: a data directory on a tiny file system that fills
// up. The coordinator must keep its promises when it cannot write: acknowledgements and
// deletions go through (so space comes back while it runs), it starts on a full disk, and
// nothing a client acknowledged is rendered again.
#include <gtest/gtest.h>
#include <signal.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "farm_harness.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

// A small, long animation: `frames` frames of 64x48 at 1 spp (about 49 KiB of tile data each).
fs::path long_scene(const fs::path& dir, int frames) {
  const fs::path p = dir / "long.json";
  std::ofstream(p) << R"({
  "camera": { "position": [0, 1.6, 6.5], "look_at": [0, 0.9, 0], "up": [0, 1, 0], "vfov_deg": 40 },
  "image": { "width": 64, "height": 48, "spp": 1, "max_depth": 4, "seed": 1 },
  "background": [0.25, 0.45, 0.8],
  "lights": [ { "type": "point", "position": [-4, 6, 5], "intensity": 160 } ],
  "materials": { "matte": { "type": "diffuse", "albedo": [0.2, 0.5, 0.25] },
                 "mirror": { "type": "mirror", "reflectance": 0.9 } },
  "objects": [
    { "type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "matte" },
    { "type": "sphere", "name": "ball", "center": [0, 1, 0], "radius": 1, "material": "mirror" }
  ],
  "animation": { "frames": )" << frames << R"(,
    "objects": { "ball": [ { "frame": 0, "translate": [-2, 0, 0] }, { "frame": )" << frames - 1
                                   << R"(, "translate": [2, 0, 0] } ] } }
})";
  return p;
}

struct SmallDisk {
  fs::path path;
  bool mounted = false;
  SmallDisk(const fs::path& p, const char* size) : path(p) {
    fs::create_directories(p);
    mounted = mount("tmpfs", p.c_str(), "tmpfs", 0, (std::string("size=") + size).c_str()) == 0;
  }
  ~SmallDisk() {
    if (mounted) umount2(path.c_str(), MNT_DETACH);
  }
};

bool wait_log(Process& p, const std::string& needle, std::chrono::seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (p.log().find(needle) != std::string::npos) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

TEST(FarmExhaustion, FullDiskReclaimsAcknowledgedFramesWhileRunningAndRestarts) {
  Farm farm;
  SmallDisk disk(farm.dir() / "small", "2m");
  if (!disk.mounted) GTEST_SKIP() << "cannot mount a small tmpfs here (" << std::strerror(errno) << ")";
  constexpr int kFrames = 60;  // ~2.9 MiB of tiles: more than the disk holds
  const fs::path scene = long_scene(farm.dir(), kFrames);
  farm.start_server({"--data-dir", (disk.path / "data").string()});
  farm.start_worker("w1", 2);
  // Nobody fetches the frames yet: the disk fills with unacknowledged tiles.
  CliResult s = farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--tile", "64", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  ASSERT_TRUE(wait_log(farm.server(), "No space left on device", 120s)) << farm.server().log();
  ASSERT_TRUE(farm.wait_tiles_done(job, kFrames, 120s));  // done in memory
  // A client now takes every frame (from the coordinator's memory) and acknowledges it: those
  // acknowledgements must not wait behind the tile writes that cannot fit.
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string()});
  ASSERT_EQ(w.code, 0) << w.output << farm.server().log();
  for (int f : {0, kFrames / 2, kFrames - 1}) {
    char name[32];
    std::snprintf(name, sizeof name, "f_%04d.exr", f);
    EXPECT_EQ(compare_exr(out / name, reference_frame(scene, f, {})), "") << "frame " << f;
  }
  // Space comes back by itself (nothing was removed from the disk by hand): the coordinator
  // recovers and takes new jobs.
  ASSERT_TRUE(wait_log(farm.server(), "storage recovered", 60s)) << farm.server().log();
  CliResult again =
      farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--frames", "0", "--detach"});
  EXPECT_EQ(again.code, 0) << again.output << farm.server().log();
  // Stop, start again: the acknowledged job is done and delivered; no tile of it is rendered
  // again (no result for it reaches the new coordinator).
  farm.workers().clear();
  farm.server().signal(SIGTERM);
  ASSERT_EQ(farm.server().wait(30s), 0) << farm.server().log();
  farm.start_server(farm.server_extra());
  farm.start_worker("w2", 2);
  CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(st.code, 0) << st.output;
  const auto j = nlohmann::json::parse(st.output);
  EXPECT_EQ(j.at("state"), "done") << st.output;
  EXPECT_EQ(j.at("frames_acknowledged").size(), size_t(kFrames)) << st.output;
  std::this_thread::sleep_for(500ms);  // let the new worker pull whatever is queued (there must be nothing of `job`)
  EXPECT_EQ(farm.server().log().find("job " + job + " frame"), std::string::npos) << farm.server().log();
}

TEST(FarmExhaustion, CoordinatorStartsOnAFullDiskAndServesWhatItHas) {
  Farm farm;
  SmallDisk disk(farm.dir() / "small", "1m");
  if (!disk.mounted) GTEST_SKIP() << "cannot mount a small tmpfs here (" << std::strerror(errno) << ")";
  const fs::path scene = source("tests/farm/whitted_orbit.json");
  farm.start_server({"--data-dir", (disk.path / "data").string()});
  farm.start_worker("w1");
  CliResult s = farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--frames", "0", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);
  ASSERT_TRUE(farm.wait_tiles_done(job, 6, 60s));
  farm.workers().clear();
  farm.server().signal(SIGTERM);
  ASSERT_EQ(farm.server().wait(30s), 0) << farm.server().log();
  {
    std::ofstream fill(disk.path / "filler", std::ios::binary);
    const std::string kb(1024, 'x');
    while (fill.write(kb.data(), kb.size())) {
    }
  }
  farm.start_server(farm.server_extra());  // throws if it exits
  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string()});
  EXPECT_EQ(w.code, 0) << w.output << farm.server().log();
  EXPECT_EQ(compare_exr(out / "f_0000.exr", reference_frame(scene, 0, {})), "");
}

// tessera-server on 127.0.0.1:0 under `prlimit LIMIT` (e.g. --nofile=SOFT:HARD), its data in the
// farm's folder, with `extra` arguments, on `port` (0: any), its log in `log_name` (a new name for each
// start: a restart's log must not show the last start's "listening on"); `port` is 0 if it did
// not say where it listens.
struct LimitedServer {
  std::unique_ptr<Process> process;
  int port = 0;
  std::string address() const { return "127.0.0.1:" + std::to_string(port); }
};
LimitedServer start_limited_server(const Farm& farm, const std::string& limit,
                                   const std::vector<std::string>& extra = {}, int port = 0,
                                   const std::string& log_name = "server.log") {
  LimitedServer s;
  std::vector<std::string> argv{"/usr/bin/prlimit",
                                limit,
                                bin("tessera-server").string(),
                                "--listen",
                                "127.0.0.1:" + std::to_string(port),
                                "--data-dir",
                                (farm.dir() / "data").string()};
  argv.insert(argv.end(), extra.begin(), extra.end());
  s.process = std::make_unique<Process>(argv, farm.dir() / log_name);
  const std::regex re("listening on 127\\.0\\.0\\.1:([0-9]+)");
  std::smatch m;
  std::string log;
  for (int i = 0; i < 800 && !std::regex_search(log = s.process->log(), m, re); ++i) std::this_thread::sleep_for(25ms);
  if (!m.empty()) s.port = std::stoi(m[1]);
  return s;
}

// Descriptors the process holds now.
int open_descriptors(int pid) {
  int n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    ++n;
  }
  return n;
}

TEST(FarmExhaustion, IdleConnectionsDoNotExhaustTheCoordinatorsDescriptors) {
  // The coordinator starts with a soft limit of 256 descriptors (hard: 4096), as a default
  // `ulimit -n` would give it; 600 connections that never send a byte then arrive.
  rlim_t hard = 0;
  if (!own_descriptors(2048, &hard)) GTEST_SKIP() << "this test needs 2048 descriptors, the hard limit is " << hard;
  Farm farm;
  LimitedServer s = start_limited_server(farm, "--nofile=256:4096");
  Process& server = *s.process;
  ASSERT_NE(s.port, 0) << server.log();
  const std::string address = s.address();
  EXPECT_NE(server.log().find("descriptor limit 4096 (was 256"), std::string::npos) << server.log();
  const std::vector<int> idle = silent_connections(s.port, 600);
  ASSERT_EQ(idle.size(), 600u) << std::strerror(errno);
  // Still serving while they are open...
  CliResult h = farm.cli({"health", "--coordinator", address, "--timeout", "20"}, 60s);
  EXPECT_EQ(h.code, 0) << h.output << server.log();
  // ...and it does not keep them: connections that never complete their handshake are closed
  // (10 s), so the descriptors come back while the peers still hold their ends.
  bool released = false;
  for (int i = 0; i < 600 && !released; ++i) {
    released = open_descriptors(server.pid()) < 200;
    if (!released) std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(released) << open_descriptors(server.pid()) << " descriptors still open";
  for (int fd : idle) close(fd);
  CliResult h2 = farm.cli({"health", "--coordinator", address, "--timeout", "20"}, 60s);
  EXPECT_EQ(h2.code, 0) << h2.output;
}

// A connection flood at the descriptor limit, reproduced: soft and hard limit 200, as a container
// or a systemd unit may set them, and 300 connections that send nothing, held 3 s, then closed.
// gRPC 1.51 alone stops accepting for good at the first EMFILE; with the accept guard
// (farm/accept_guard.h) the coordinator sheds what it cannot take, then serves again: a health
// check answers and a job renders, bit-identical to `tessera render`.
TEST(FarmExhaustion, AConnectionFloodAtTheHardLimitDoesNotStopTheCoordinator) {
  rlim_t hard = 0;
  if (!own_descriptors(1024, &hard)) GTEST_SKIP() << "this test needs 1024 descriptors, the hard limit is " << hard;
  Farm farm;
  LimitedServer s = start_limited_server(farm, "--nofile=200:200");
  Process& server = *s.process;
  ASSERT_NE(s.port, 0) << server.log();
  const std::string address = s.address();
  {
    const std::vector<int> flood = silent_connections(s.port, 300);
    ASSERT_EQ(flood.size(), 300u) << std::strerror(errno);
    std::this_thread::sleep_for(3s);
    for (int fd : flood) close(fd);
  }
  EXPECT_NE(server.log().find("out of descriptors"), std::string::npos) << server.log();
  CliResult h = farm.cli({"health", "--coordinator", address, "--timeout", "20"}, 60s);
  EXPECT_EQ(h.code, 0) << h.output << server.log();
  // Not just alive: a worker joins and a frame is delivered whole.
  const fs::path scene = long_scene(farm.dir(), 2);
  Process worker({bin("tessera-worker").string(), "--coordinator", address, "--threads", "1", "--name", "w"},
                 farm.dir() / "worker.log");
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", scene.string(), "--coordinator", address, "--frames", "0", "-o",
                          (out / "f_####.exr").string(), "--tile", "16"});
  ASSERT_EQ(r.code, 0) << r.output << server.log();
  EXPECT_EQ(compare_exr(out / "f_0000.exr", reference_frame(scene, 0, {})), "");
}

// A job is bounded by what it costs the coordinator in memory: the tiles of the frames it has
// started and no client has received. One whose single frame is over --max-job-tiles is refused
// naming the flag and the count; one whose next frame would go over waits, says so in `tessera
// status`, and renders on as a client receives its frames; a new job that could not start its
// first frame beside the frames held is refused naming --max-resident-tiles. Nothing is lost.
TEST(FarmExhaustion, AJobWaitsForItsFramesToBeReceivedAndOversizedOnesAreRefusedByName) {
  Farm farm;
  farm.start_server({"--max-job-tiles", "400", "--max-resident-tiles", "500"});
  const fs::path scene = long_scene(farm.dir(), 6);  // 64x48: 16 x 12 = 192 tiles of 4 px a frame
  const auto submit = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> args{"submit", scene.string(), "--coordinator", farm.address(), "--detach"};
    args.insert(args.end(), extra.begin(), extra.end());
    return farm.cli(args);
  };
  CliResult big = submit({"--tile", "4", "--width", "128"});  // 32 x 12 = 384 tiles a frame: fits
  ASSERT_EQ(big.code, 0) << big.output;
  ASSERT_EQ(farm.cli({"cancel", job_id_from(big.output), "--coordinator", farm.address()}).code, 0);
  CliResult huge = submit({"--tile", "4", "--width", "160"});  // 40 x 12 = 480 tiles a frame
  EXPECT_NE(huge.code, 0) << huge.output;
  EXPECT_NE(huge.output.find("480"), std::string::npos) << huge.output;
  EXPECT_NE(huge.output.find("--max-job-tiles"), std::string::npos) << huge.output;

  CliResult first = submit({"--tile", "4"});  // 6 frames of 192 tiles: two fit under 400
  ASSERT_EQ(first.code, 0) << first.output;
  const std::string job = job_id_from(first.output);
  farm.start_worker("w", 2);
  nlohmann::json st;
  ASSERT_TRUE(poll_until(60s, [&] {
    CliResult r = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
    if (r.code != 0) return false;
    st = nlohmann::json::parse(r.output);
    return st.value("waiting_for_memory", false) && st.value("tiles_done", 0) == 384;
  })) << st.dump() << farm.server_logs();
  EXPECT_EQ(st.value("tiles_resident", 0), 384);
  EXPECT_EQ(st.value("state", std::string()), "running");
  CliResult human = farm.cli({"status", job, "--coordinator", farm.address()});
  EXPECT_NE(human.output.find("waiting for memory"), std::string::npos) << human.output;
  // 384 held + 192 of a new job's first frame: over 500.
  CliResult second = submit({"--tile", "4"});
  EXPECT_NE(second.code, 0) << second.output;
  EXPECT_NE(second.output.find("--max-resident-tiles"), std::string::npos) << second.output;
  EXPECT_NE(second.output.find("576"), std::string::npos) << second.output;

  // A client receives the frames: the job renders to its end, every frame as `tessera render`.
  const fs::path out = farm.dir() / "out";
  CliResult watched = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "f_####.exr").string()});
  ASSERT_EQ(watched.code, 0) << watched.output << farm.server_logs();
  for (int f = 0; f < 6; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "f_%04d.exr", f);
    EXPECT_EQ(compare_exr(out / name, reference_frame(scene, f, {"--tile", "4"})), "") << name;
  }
  CliResult done = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
  ASSERT_EQ(done.code, 0) << done.output;
  EXPECT_EQ(nlohmann::json::parse(done.output).value("state", std::string()), "done");
  EXPECT_EQ(nlohmann::json::parse(done.output).value("tiles_resident", -1), 0);
  EXPECT_EQ(submit({"--tile", "4"}).code, 0) << "the frames were received: memory is free again";
}

// A job stored under higher limits (here: the defaults) that a restart cannot fit under the limits
// it runs with now is not built at start: it is failed, by name, and stays failed at later
// starts; the coordinator serves on. (Before, such a job took the coordinator's memory at every
// start, and one too big for the machine crash-looped it.)
TEST(FarmExhaustion, AStoredJobOverTheLimitIsFailedByNameAtStartNotRebuilt) {
  Farm farm;
  farm.start_server();
  const fs::path scene = long_scene(farm.dir(), 10);
  CliResult a = farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--tile", "4", "--detach"});
  ASSERT_EQ(a.code, 0) << a.output;
  const std::string job = job_id_from(a.output);
  farm.stop_server();
  farm.start_server({"--max-job-tiles", "100"});
  EXPECT_NE(farm.server().log().find("not restored at start"), std::string::npos) << farm.server().log();
  const auto state_and_error = [&] {
    CliResult st = farm.cli({"status", job, "--json", "--coordinator", farm.address()});
    EXPECT_EQ(st.code, 0) << st.output;
    const auto j = nlohmann::json::parse(st.output);
    return std::pair{j.value("state", std::string()), j.value("error", std::string())};
  };
  auto [state, error] = state_and_error();
  EXPECT_EQ(state, "failed");
  EXPECT_NE(error.find("192 tiles a frame"), std::string::npos) << error;
  EXPECT_NE(error.find("--max-job-tiles"), std::string::npos) << error;
  // Not loaded again, even with the limit gone; and the farm renders on.
  farm.stop_server();
  farm.start_server();
  EXPECT_EQ(farm.server().log().find("not restored at start"), std::string::npos) << farm.server().log();
  std::tie(state, error) = state_and_error();
  EXPECT_EQ(state, "failed");
  farm.start_worker("w");
  const fs::path out = farm.dir() / "out";
  CliResult r = farm.cli({"submit", scene.string(), "--coordinator", farm.address(), "--frames", "0", "--tile", "16",
                          "-o", (out / "f_####.exr").string()});
  ASSERT_EQ(r.code, 0) << r.output << farm.server().log();
  EXPECT_EQ(compare_exr(out / "f_0000.exr", reference_frame(scene, 0, {})), "");
}

// A job's memory does not grow with its frames or its tiles: 10,000 frames of 8192x8192 in 4-px
// tiles (42 billion tiles; at ~100 bytes a tile, 4 TB of tile tables if they were built at
// submit) are accepted under the default limits, under a 3 GB address-space cap, and keep the
// coordinator small after submit and after a kill -9 and restart; the farm renders the next job.
TEST(FarmExhaustion, AJobOfTenThousandHugeFramesCostsTheCoordinatorNoMemoryPerTile) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "a sanitizer's shadow memory does not fit under an address-space cap";
#endif
  Farm farm;
  const fs::path scene = long_scene(farm.dir(), 10000);
  LimitedServer s = start_limited_server(farm, "--as=3000000000");
  ASSERT_NE(s.port, 0) << s.process->log();
  CliResult big = farm.cli({"submit", scene.string(), "--coordinator", s.address(), "--tile", "4", "--width", "8192",
                            "--height", "8192", "--detach"});
  ASSERT_EQ(big.code, 0) << big.output << s.process->log();
  const std::string job = job_id_from(big.output);
  const auto check = [&](const char* when) {
    CliResult st = farm.cli({"status", job, "--json", "--coordinator", s.address()});
    ASSERT_EQ(st.code, 0) << st.output;
    const auto j = nlohmann::json::parse(st.output);
    EXPECT_EQ(j.value("tiles_total", int64_t(0)), int64_t(10000) * 2048 * 2048) << when;
    EXPECT_EQ(j.value("tiles_resident", int64_t(-1)), 0) << when;
    EXPECT_EQ(j.value("state", std::string()), "queued") << when;
    const double peak = peak_rss_mib(s.process->pid());
    RecordProperty(std::string("peak_rss_mib_") + when, int(peak));
    if (kRssMeaningful) EXPECT_LT(peak, 300) << when;
  };
  check("after_submit");
  s.process->signal(SIGKILL);
  s.process->wait(10s);
  s = start_limited_server(farm, "--as=3000000000", {}, s.port, "server-restarted.log");
  ASSERT_NE(s.port, 0) << s.process->log();
  check("after_restart");
  CliResult small = farm.cli({"submit", scene.string(), "--coordinator", s.address(), "--frames", "0", "--detach"});
  EXPECT_EQ(small.code, 0) << small.output << s.process->log();
}

}  // namespace
}  // namespace tessera::farmtest

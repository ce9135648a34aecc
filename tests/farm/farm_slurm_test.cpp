// SPDX-License-Identifier: Apache-2.0
// Workers placed by Slurm (docker/slurm/tessera-workers.sbatch) on a real single-node Slurm on
// localhost: the batch script as users submit it, a 2-task array, each task one tessera-worker
// with the task's CPU and the worker token from a file, leaving with --exit-when-idle once the
// queue is empty.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <thread>

#include "farm_harness.h"
#include "slurm_cluster.h"

namespace tessera::farmtest {
namespace {

using namespace std::chrono_literals;

const fs::path kScene = source("tests/farm/whitted_orbit.json");  // 96x64, 3 frames: 72 tiles at 16 px

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(FarmSlurm, AnArrayOfWorkersRendersTheJobAndEndsWithTheQueue) {
  if (const auto why = SlurmCluster::cannot_run()) GTEST_SKIP() << *why;
  Farm farm;
  // Workers need a token here: the script must hand its file to tessera-worker.
  const fs::path token = farm.dir() / "worker.token";
  std::ofstream(token) << "slurm-worker-secret-7f3\n";
  farm.start_server({"--worker-token-file", token.string()});
  SlurmCluster slurm(farm.dir() / "slurm");

  // The job first: a worker that found the queue empty for its idle time would rightly leave.
  CliResult s = farm.cli({"submit", kScene.string(), "--coordinator", farm.address(), "--tile", "16", "--detach"});
  ASSERT_EQ(s.code, 0) << s.output;
  const std::string job = job_id_from(s.output);

  // As a user submits it: the coordinator in the environment, arguments after the script's name
  // for tessera-worker (50 ms more a tile, so that both tasks get tiles of this small job).
  const fs::path tasks = farm.dir() / "tasks";
  fs::create_directories(tasks);
  const CliResult sb = slurm.run(
      "cd '" + tasks.string() + "' && TESSERA_COORDINATOR=" + farm.address() + " TESSERA_WORKER_TOKEN_FILE='" +
      token.string() + "' TESSERA_WORKER_BIN='" +
      bin("tessera-worker").string() + "' TMPDIR='" + tasks.string() + "' sbatch --parsable --array=0-1 --cpus-per-task=1 '" +
      source("docker/slurm/tessera-workers.sbatch").string() + "' --exit-when-idle 2 --test-delay-ms 50");
  ASSERT_EQ(sb.code, 0) << sb.output << slurm.logs();
  const std::string array = sb.output.substr(0, sb.output.find_first_of(";\n"));

  const fs::path out = farm.dir() / "out";
  CliResult w = farm.cli({"watch", job, "--coordinator", farm.address(), "-o", (out / "frame_####.exr").string()}, 90s);
  ASSERT_EQ(w.code, 0) << w.output << slurm.show_job(array) << slurm.logs();
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(compare_exr(out / ("frame_000" + std::to_string(f) + ".exr"), reference_frame(kScene, f, {})), "")
        << "frame " << f;
  }

  // Both tasks end by themselves once the queue is empty, with status 0.
  std::string shown;
  for (int i = 0; i < 300; ++i) {
    shown = slurm.show_job(array);
    if (count(shown, "JobState=COMPLETED") + count(shown, "JobState=FAILED") +
            count(shown, "JobState=CANCELLED") >= 2) {
      break;
    }
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(count(shown, "JobState=COMPLETED"), 2) << shown << slurm.logs();
  EXPECT_EQ(count(shown, "ExitCode=0:0"), 2) << shown;

  // Each task ran one worker with the task's CPU, logged to its own file, rendered tiles and
  // left because the farm had nothing more for it.
  int results = 0;
  for (int t = 0; t < 2; ++t) {
    const fs::path log = tasks / ("tessera-worker-" + array + "_" + std::to_string(t) + ".log");
    ASSERT_TRUE(fs::exists(log)) << log << "\n" << shown;
    const std::string text = read_text(log);
    EXPECT_NE(text.find("(1 threads"), std::string::npos) << text;
    EXPECT_NE(text.find("--exit-when-idle"), std::string::npos) << text;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(text, m, std::regex(R"(sent (\d+) results)"))) << text;
    EXPECT_GT(std::stoi(m[1]), 0) << "task " << t << " rendered nothing:\n" << text;
    results += std::stoi(m[1]);
  }
  EXPECT_GE(results, 72);
}

}  // namespace
}  // namespace tessera::farmtest

// SPDX-License-Identifier: Apache-2.0
// Real processes on loopback for the farm tests: a coordinator on an ephemeral port, workers,
// and the CLI, all in a temporary directory. Every child gets PR_SET_PDEATHSIG, so a test that
// crashes or is killed by CTest's timeout takes its processes with it; destructors SIGKILL
// whatever is still running when a test fails early.
#pragma once

#include <sys/resource.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace tessera::farmtest {

namespace fs = std::filesystem;

class Process {
 public:
  Process(const std::vector<std::string>& argv, const fs::path& log);
  ~Process();
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  void signal(int sig);
  // Exit code, 128+signal if killed, or -1 on timeout (the process is then killed).
  int wait(std::chrono::milliseconds timeout);
  bool running();
  std::string log() const;
  int pid() const { return pid_; }

 private:
  int pid_ = -1;
  int status_ = -1;
  bool reaped_ = false;
  fs::path log_;
};

struct CliResult {
  int code = -1;
  std::string output;  // stdout and stderr
};

fs::path bin(const std::string& name);  // built binaries
// The threads of process `pid` in which signal `sig` is not blocked, by name (from /proc; a
// thread in sigwait for `sig` counts, as the kernel counts it). Empty if the process is gone.
std::vector<std::string> threads_taking(int pid, int sig);
fs::path source(const std::string& rel);
std::string read_text(const fs::path& p);

class Farm {
 public:
  Farm();  // a fresh temporary directory
  ~Farm();

  // Starts tessera-server on 127.0.0.1:0 (the first time; later on the same port) with its data
  // in dir()/server-data, and waits for its "listening on" line.
  void start_server(const std::vector<std::string>& extra = {});
  // kill -9 the coordinator, then start it again on the same port and data dir (same extra args).
  void restart_server(std::chrono::milliseconds down = std::chrono::milliseconds(0));
  // kill -9 the coordinator and wait for it (a test then damages its files and calls
  // start_server() again, which reuses the port).
  void stop_server();
  const std::vector<std::string>& server_extra() const { return server_extra_; }
  // Every coordinator log of this farm, oldest first (one per start).
  std::string server_logs() const;
  fs::path data_dir() const { return dir_ / "server-data"; }
  Process& start_worker(const std::string& name, int threads = 1, int delay_ms = 0,
                        const std::vector<std::string>& extra = {});
  // Runs `tessera ARGS --coordinator ADDRESS`-style commands (address appended by the caller).
  CliResult cli(const std::vector<std::string>& args, std::chrono::seconds timeout = std::chrono::seconds(120));
  std::unique_ptr<Process> cli_async(const std::vector<std::string>& args, const std::string& log_name);
  // Polls `tessera status JOB --json` until tiles_done >= n (or the job ended). False on timeout.
  bool wait_tiles_done(const std::string& job, int n, std::chrono::seconds timeout = std::chrono::seconds(60));
  int tiles_done(const std::string& job, std::string* state = nullptr);

  const std::string& address() const { return address_; }
  const fs::path& dir() const { return dir_; }
  Process& server() { return *server_; }
  std::vector<std::unique_ptr<Process>>& workers() { return workers_; }

 private:
  fs::path dir_;
  std::string address_;
  std::unique_ptr<Process> server_;
  std::vector<std::string> server_extra_;
  int server_starts_ = 0;
  std::vector<std::unique_ptr<Process>> workers_;
  int cli_runs_ = 0;
};

// Calls `done` every 50 ms until it returns true (true) or `timeout` passes (false).
template <class Fn>
bool poll_until(std::chrono::milliseconds timeout, Fn done) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

// Peak resident memory of a process, in MiB (VmHWM); negative when it cannot be read.
double peak_rss_mib(int pid);
// ASan keeps freed memory in quarantine (256 MiB by default) and adds shadow memory, so a peak
// RSS says nothing about the coordinator's own use there: bounds on it are checked in the plain
// build only (the sanitizer build still runs the requests and checks their answers).
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kRssMeaningful = false;
#else
inline constexpr bool kRssMeaningful = true;
#endif

// Raises this process's soft descriptor limit to its hard one; false (the test skips) when that
// is under `need`.
bool own_descriptors(rlim_t need, rlim_t* hard);

// A TCP port on 127.0.0.1 that was free a moment ago (for programs that take a port, not 0).
int free_port();

// `n` TCP connections to 127.0.0.1:port that send nothing (fewer if one fails: the caller
// checks); the caller closes them.
std::vector<int> silent_connections(int port, int n);

// Renders frame F of the scene in-process with `tessera render` (cached per scene+args).
fs::path reference_frame(const fs::path& scene, int frame, const std::vector<std::string>& args);
// Empty if the two EXRs have identical pixels; else a description of the first difference.
std::string compare_exr(const fs::path& a, const fs::path& b);
// The job id from a `tessera submit` output ("job ID submitted ...").
std::string job_id_from(const std::string& output);
// The job id a running `tessera submit` prints, waiting up to 10 s for it; empty if none came.
std::string wait_job_id(const Process& client);

}  // namespace tessera::farmtest

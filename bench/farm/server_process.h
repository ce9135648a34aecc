// SPDX-License-Identifier: Apache-2.0
// A tessera-server child process for the coordinator benchmark, and what /proc says about it:
// CPU time (user + system) and memory (VmRSS, VmHWM). The child dies with the benchmark
// (PR_SET_PDEATHSIG), so an interrupted run leaves no coordinator behind.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

namespace tessera::bench {

struct ProcStat {
  double cpu_seconds = 0;  // utime + stime
  long rss_kb = 0;         // VmRSS
  long hwm_kb = 0;         // VmHWM: peak resident set
  int threads = 0;
};

// Reads /proc/PID/stat and /proc/PID/status. Throws std::runtime_error if the process is gone.
ProcStat proc_stat(pid_t pid);

// Confines the calling process to `cpus` (sched_setaffinity); empty: leaves it as it is.
// Throws std::runtime_error naming the CPU list if the kernel refuses it.
void pin_to_cpus(const std::vector<int>& cpus);

// "0-3,8" -> {0,1,2,3,8}. Throws std::invalid_argument naming the part it cannot read.
std::vector<int> parse_cpu_list(const std::string& text);

class ServerProcess {
 public:
  // Starts `exe --listen 127.0.0.1:0 --data-dir DIR/data EXTRA...` with stdout and stderr in
  // DIR/server.log, and waits (up to 20 s) for its "listening on HOST:PORT" line. A non-empty
  // `cpus` confines the coordinator to those CPUs (for scaling runs: its cores against the work).
  ServerProcess(const std::filesystem::path& exe, const std::filesystem::path& dir,
                const std::vector<std::string>& extra, const std::vector<int>& cpus = {});
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  const std::string& address() const { return address_; }
  pid_t pid() const { return pid_; }
  ProcStat stat() const { return proc_stat(pid_); }
  // SIGTERM, then SIGKILL after `grace`. Returns the exit status (128 + signal if killed).
  int stop(std::chrono::milliseconds grace = std::chrono::milliseconds(5000));

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
  std::string address_;
  std::filesystem::path log_;
};

}  // namespace tessera::bench

// SPDX-License-Identifier: Apache-2.0
#include "server_process.h"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace tessera::bench {

namespace fs = std::filesystem;

ProcStat proc_stat(pid_t pid) {
  ProcStat s;
  const std::string base = "/proc/" + std::to_string(pid);
  std::ifstream stat(base + "/stat");
  std::string line;
  if (!std::getline(stat, line)) throw std::runtime_error("process " + std::to_string(pid) + " is gone");
  // Fields after the command name, which is in parentheses and may contain spaces.
  std::istringstream rest(line.substr(line.rfind(')') + 2));
  std::vector<std::string> f;
  for (std::string x; rest >> x;) f.push_back(x);
  // rest starts at field 3 (state): utime is field 14, stime field 15.
  const double hz = double(sysconf(_SC_CLK_TCK));
  s.cpu_seconds = (std::stod(f.at(11)) + std::stod(f.at(12))) / hz;
  std::ifstream status(base + "/status");
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) s.rss_kb = std::stol(line.substr(6));
    if (line.rfind("VmHWM:", 0) == 0) s.hwm_kb = std::stol(line.substr(6));
    if (line.rfind("Threads:", 0) == 0) s.threads = std::stoi(line.substr(8));
  }
  return s;
}

void pin_to_cpus(const std::vector<int>& cpus) {
  if (cpus.empty()) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  std::string names;
  for (int c : cpus) {
    CPU_SET(c, &set);
    names += (names.empty() ? "" : ",") + std::to_string(c);
  }
  if (sched_setaffinity(0, sizeof set, &set) != 0) throw std::runtime_error("cannot run on CPUs " + names);
}

std::vector<int> parse_cpu_list(const std::string& text) {
  std::vector<int> out;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, ',');) {
    const std::regex range(R"(\s*(\d+)\s*(?:-\s*(\d+))?\s*)");
    std::smatch m;
    if (!std::regex_match(part, m, range)) throw std::invalid_argument("CPU list '" + text + "': cannot read '" + part + "'");
    const int lo = std::stoi(m[1]), hi = m[2].matched ? std::stoi(m[2]) : lo;
    if (hi < lo || hi >= CPU_SETSIZE) throw std::invalid_argument("CPU list '" + text + "': bad range '" + part + "'");
    for (int c = lo; c <= hi; ++c) out.push_back(c);
  }
  return out;
}

ServerProcess::ServerProcess(const fs::path& exe, const fs::path& dir, const std::vector<std::string>& extra,
                             const std::vector<int>& cpus) {
  fs::create_directories(dir / "data");
  log_ = dir / "server.log";
  std::vector<std::string> argv = {exe.string(), "--listen", "127.0.0.1:0", "--data-dir", (dir / "data").string()};
  argv.insert(argv.end(), extra.begin(), extra.end());
  const pid_t parent = getpid();
  pid_ = fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    try {
      pin_to_cpus(cpus);
    } catch (const std::exception&) {
      _exit(126);
    }
    const int fd = open(log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, 1);
      dup2(fd, 2);
      close(fd);
    }
    std::vector<char*> args;
    for (auto& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  const std::regex re("listening on ([0-9.]+:[0-9]+)");
  for (int i = 0; i < 400; ++i) {
    std::ifstream in(log_);
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string text = ss.str();
    std::smatch m;
    if (std::regex_search(text, m, re)) {
      address_ = m[1];
      return;
    }
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      reaped_ = true;
      throw std::runtime_error(exe.string() + " exited at start-up: " + text);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  stop();
  throw std::runtime_error(exe.string() + " did not print 'listening on' within 20 s (log: " + log_.string() + ")");
}

ServerProcess::~ServerProcess() {
  if (!reaped_) stop(std::chrono::milliseconds(0));
}

int ServerProcess::stop(std::chrono::milliseconds grace) {
  if (reaped_) return 0;
  kill(pid_, grace.count() > 0 ? SIGTERM : SIGKILL);
  const auto deadline = std::chrono::steady_clock::now() + grace;
  int status = 0;
  for (;;) {
    const pid_t r = waitpid(pid_, &status, WNOHANG);
    if (r == pid_) break;
    if (std::chrono::steady_clock::now() >= deadline) {
      kill(pid_, SIGKILL);
      waitpid(pid_, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  reaped_ = true;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace tessera::bench

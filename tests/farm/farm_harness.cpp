// SPDX-License-Identifier: Apache-2.0
#include "farm_harness.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "image/exr_io.h"

namespace tessera::farmtest {

using namespace std::chrono_literals;

Process::Process(const std::vector<std::string>& argv, const fs::path& log) : log_(log) {
  const pid_t parent = getpid();
  pid_ = fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);  // the parent died before prctl
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    // Children must never inherit a blocked signal mask, an ignored signal or the test's stdin:
    // they start as a container or a shell starts them. (exec keeps SIG_IGN: the shell that runs
    // the tests may ignore SIGPIPE, which would hide a daemon that dies of it.)
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, nullptr);
    for (int sig = 1; sig < NSIG; ++sig) ::signal(sig, SIG_DFL);  // SIGKILL/SIGSTOP refuse: fine
    const int devnull = open("/dev/null", O_RDONLY);
    dup2(devnull, 0);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    std::fprintf(stderr, "exec %s: %s\n", args[0], std::strerror(errno));
    _exit(127);
  }
}

Process::~Process() {
  if (!reaped_) {
    kill(pid_, SIGKILL);
    waitpid(pid_, &status_, 0);
  }
}

void Process::signal(int sig) {
  if (!reaped_) kill(pid_, sig);
}

bool Process::running() {
  if (reaped_) return false;
  if (waitpid(pid_, &status_, WNOHANG) == pid_) reaped_ = true;
  return !reaped_;
}

int Process::wait(std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (running()) {
    if (std::chrono::steady_clock::now() > end) {
      kill(pid_, SIGKILL);
      waitpid(pid_, &status_, 0);
      reaped_ = true;
      return -1;
    }
    std::this_thread::sleep_for(20ms);
  }
  if (WIFEXITED(status_)) return WEXITSTATUS(status_);
  if (WIFSIGNALED(status_)) return 128 + WTERMSIG(status_);
  return -1;
}

std::string Process::log() const { return read_text(log_); }

fs::path bin(const std::string& name) {
  if (name == "tessera") return fs::path(TESSERA_BINARY_DIR) / "client" / "tessera";
  if (name == "tessera-server") return fs::path(TESSERA_BINARY_DIR) / "server" / "tessera-server";
  return fs::path(TESSERA_BINARY_DIR) / "worker" / "tessera-worker";
}

std::vector<std::string> threads_taking(int pid, int sig) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& task : fs::directory_iterator(fs::path("/proc") / std::to_string(pid) / "task", ec)) {
    std::istringstream status(read_text(task.path() / "status"));
    std::string line;
    while (std::getline(status, line)) {
      if (line.rfind("SigBlk:", 0) != 0) continue;
      const uint64_t blocked = std::stoull(line.substr(7), nullptr, 16);
      if (!(blocked & (uint64_t(1) << (sig - 1)))) {
        std::string name = read_text(task.path() / "comm");
        while (!name.empty() && name.back() == '\n') name.pop_back();
        out.push_back(task.path().filename().string() + " " + name);
      }
    }
  }
  return out;
}

fs::path source(const std::string& rel) { return fs::path(TESSERA_SOURCE_DIR) / rel; }

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Farm::Farm() {
  std::string templ = (fs::temp_directory_path() / "tessera-farm-XXXXXX").string();
  if (!mkdtemp(templ.data())) throw std::runtime_error("mkdtemp failed");
  dir_ = templ;
}

Farm::~Farm() {
  workers_.clear();
  server_.reset();
  std::error_code ec;
  if (!std::getenv("TESSERA_KEEP_TEST_DIRS")) fs::remove_all(dir_, ec);
}

void Farm::start_server(const std::vector<std::string>& extra) {
  server_extra_ = extra;
  std::vector<std::string> argv{bin("tessera-server"), "--listen", address_.empty() ? "127.0.0.1:0" : address_};
  // Defaults that `extra` may replace (CLI11 refuses an option given twice).
  for (const auto& [opt, value] : {std::pair<std::string, std::string>{"--data-dir", data_dir().string()},
                                   {"--log-level", "debug"}}) {
    if (std::find(extra.begin(), extra.end(), opt) == extra.end()) argv.insert(argv.end(), {opt, value});
  }
  argv.insert(argv.end(), extra.begin(), extra.end());
  const int n = ++server_starts_;
  server_ = std::make_unique<Process>(argv, dir_ / (n == 1 ? "server.log" : "server-" + std::to_string(n) + ".log"));
  const std::regex re("listening on (127\\.0\\.0\\.1:[0-9]+)");
  const auto end = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < end) {
    std::smatch m;
    const std::string log = server_->log();
    if (std::regex_search(log, m, re)) {
      address_ = m[1];
      return;
    }
    if (!server_->running()) throw std::runtime_error("tessera-server exited:\n" + log);
    std::this_thread::sleep_for(20ms);
  }
  throw std::runtime_error("tessera-server did not report its port:\n" + server_->log());
}

void Farm::stop_server() {
  server_->signal(SIGKILL);
  server_->wait(10s);
}

void Farm::restart_server(std::chrono::milliseconds down) {
  stop_server();
  std::this_thread::sleep_for(down);
  start_server(server_extra_);
}

std::string Farm::server_logs() const {
  std::string all;
  for (int n = 1; n <= server_starts_; ++n) {
    all += read_text(dir_ / (n == 1 ? "server.log" : "server-" + std::to_string(n) + ".log"));
  }
  return all;
}

Process& Farm::start_worker(const std::string& name, int threads, int delay_ms, const std::vector<std::string>& extra) {
  std::vector<std::string> argv{bin("tessera-worker"), "--coordinator", address_, "--name", name, "--threads",
                                std::to_string(threads), "--cache-dir", (dir_ / ("cache-" + name)).string(),
                                "--test-delay-ms", std::to_string(delay_ms)};
  argv.insert(argv.end(), extra.begin(), extra.end());
  // A restarted worker (same name) appends to its log, so a test sees every incarnation.
  const fs::path log = dir_ / ("worker-" + name + ".log");
  if (fs::exists(log)) fs::rename(log, dir_ / ("worker-" + name + "-" + std::to_string(++cli_runs_) + ".log"));
  workers_.push_back(std::make_unique<Process>(argv, log));
  return *workers_.back();
}

CliResult Farm::cli(const std::vector<std::string>& args, std::chrono::seconds timeout) {
  const fs::path log = dir_ / ("cli-" + std::to_string(++cli_runs_) + ".log");
  std::vector<std::string> argv{bin("tessera")};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, log);
  CliResult r;
  r.code = p.wait(timeout);
  r.output = read_text(log);
  return r;
}

std::unique_ptr<Process> Farm::cli_async(const std::vector<std::string>& args, const std::string& log_name) {
  std::vector<std::string> argv{bin("tessera")};
  argv.insert(argv.end(), args.begin(), args.end());
  return std::make_unique<Process>(argv, dir_ / log_name);
}

int Farm::tiles_done(const std::string& job, std::string* state) {
  CliResult r = cli({"status", job, "--json", "--coordinator", address_}, 20s);
  if (r.code != 0) return -1;
  try {
    auto j = nlohmann::json::parse(r.output);
    if (state) *state = j.at("state").get<std::string>();
    return j.at("tiles_done").get<int>();
  } catch (const std::exception&) {
    return -1;
  }
}

bool Farm::wait_tiles_done(const std::string& job, int n, std::chrono::seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    std::string state;
    const int done = tiles_done(job, &state);
    if (done >= n || state == "done" || state == "cancelled") return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

fs::path reference_frame(const fs::path& scene, int frame, const std::vector<std::string>& args) {
  static std::mutex mu;
  static std::map<std::string, fs::path> cache;
  std::string key = scene.string() + "#" + std::to_string(frame);
  for (const auto& a : args) key += " " + a;
  std::lock_guard lock(mu);
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  static const fs::path dir = [] {
    std::string templ = (fs::temp_directory_path() / "tessera-farm-ref-XXXXXX").string();
    if (!mkdtemp(templ.data())) throw std::runtime_error("mkdtemp failed");
    return fs::path(templ);
  }();
  const fs::path out = dir / ("ref-" + std::to_string(cache.size()) + ".exr");
  std::vector<std::string> argv{bin("tessera"), "render", scene.string(), "-o", out.string(), "--frame",
                                std::to_string(frame), "-q"};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, dir / "render.log");
  if (p.wait(120s) != 0) throw std::runtime_error("tessera render failed:\n" + p.log());
  cache[key] = out;
  return out;
}

std::string compare_exr(const fs::path& a, const fs::path& b) {
  if (!fs::exists(a)) return a.string() + " does not exist";
  if (!fs::exists(b)) return b.string() + " does not exist";
  ImageRGB ia = read_exr(a.string()), ib = read_exr(b.string());
  if (ia.width != ib.width || ia.height != ib.height) return "sizes differ";
  for (size_t i = 0; i < ia.rgb.size(); ++i) {
    if (std::memcmp(&ia.rgb[i], &ib.rgb[i], sizeof(float)) != 0) {
      const size_t px = i / 3;
      return "pixel (" + std::to_string(px % size_t(ia.width)) + ", " + std::to_string(px / size_t(ia.width)) +
             ") channel " + std::to_string(i % 3) + ": " + std::to_string(ia.rgb[i]) + " vs " +
             std::to_string(ib.rgb[i]);
    }
  }
  return {};
}

std::string job_id_from(const std::string& output) {
  std::smatch m;
  if (std::regex_search(output, m, std::regex("job ([0-9a-f]+) submitted"))) return m[1];
  return {};
}

std::string wait_job_id(const Process& client) {
  std::string job;
  for (int i = 0; i < 400 && job.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    job = job_id_from(client.log());
  }
  return job;
}

double peak_rss_mib(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  double kib = -1;
  while (in >> key) {
    if (key == "VmHWM:") {
      in >> kib;
      break;
    }
  }
  return kib / 1024.0;
}

bool own_descriptors(rlim_t need, rlim_t* hard) {
  rlimit own{};
  getrlimit(RLIMIT_NOFILE, &own);
  *hard = own.rlim_max;
  if (own.rlim_max < need) return false;
  own.rlim_cur = own.rlim_max;
  setrlimit(RLIMIT_NOFILE, &own);
  return true;
}

int free_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
  close(fd);
  return ntohs(a.sin_port);
}

std::vector<int> silent_connections(int port, int n) {
  std::vector<int> fds;
  for (int i = 0; i < n; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) break;
    sockaddr_in sa{};
    sa.sin_family = AF_INET;
    sa.sin_port = htons(uint16_t(port));
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
      close(fd);
      break;
    }
    fds.push_back(fd);
  }
  return fds;
}

}  // namespace tessera::farmtest

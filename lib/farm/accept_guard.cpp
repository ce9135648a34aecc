// SPDX-License-Identifier: Apache-2.0
#include "farm/accept_guard.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <mutex>

namespace tessera::farm {
namespace {

std::mutex g_mu;                 // one shedding at a time: they share the spare
int g_spare = -1;                // guarded by g_mu
std::atomic<uint64_t> g_shed{0};
std::chrono::steady_clock::time_point g_last_log;  // guarded by g_mu

// The system call itself: the definition below replaces libc's in this process.
int sys_accept4(int fd, sockaddr* addr, socklen_t* len, int flags) {
  return int(::syscall(SYS_accept4, fd, addr, len, flags));
}

int open_spare() { return ::open("/dev/null", O_RDONLY | O_CLOEXEC); }

}  // namespace

void install_accept_guard() {
  std::lock_guard lock(g_mu);
  if (g_spare < 0) g_spare = open_spare();
}

// Out of descriptors while accepting on `listener`: close what waits there, report EAGAIN.
int shed_connections(int listener, int err) {
  std::lock_guard lock(g_mu);
  if (g_spare < 0) g_spare = open_spare();  // taken back after an earlier shedding could not
  uint64_t shed = 0;
  if (g_spare >= 0) {
    ::close(g_spare);
    g_spare = -1;
    // A blocking listener would block this loop once it is empty: shed one connection there.
    const bool nonblocking = (::fcntl(listener, F_GETFL) & O_NONBLOCK) != 0;
    for (;;) {
      const int c = sys_accept4(listener, nullptr, nullptr, SOCK_CLOEXEC);
      if (c < 0) break;  // drained (EAGAIN), or another thread took the freed slot (EMFILE)
      ::close(c);
      ++shed;
      if (!nonblocking) break;
    }
    g_spare = open_spare();  // fails only if another thread took the slot: retried next time
  }
  g_shed += shed;
  const auto now = std::chrono::steady_clock::now();
  if (now - g_last_log > std::chrono::seconds(1)) {  // a flood must not flood the log too
    g_last_log = now;
    spdlog::warn("out of descriptors ({}): closed {} waiting connection(s) unserved ({} since start); "
                 "accepting again once descriptors are free",
                 err == ENFILE ? "the system's" : "this process's", shed, g_shed.load());
  }
  errno = EAGAIN;
  return -1;
}

}  // namespace tessera::farm

// Replaces libc's accept4 in this process (see accept_guard.h): exported from the executable
// (lib/farm/CMakeLists.txt: --export-dynamic-symbol) so that libgrpc's calls bind here.
extern "C" int accept4(int fd, sockaddr* addr, socklen_t* len, int flags) {
  const int r = tessera::farm::sys_accept4(fd, addr, len, flags);
  if (r >= 0 || (errno != EMFILE && errno != ENFILE)) return r;
  return tessera::farm::shed_connections(fd, errno);
}

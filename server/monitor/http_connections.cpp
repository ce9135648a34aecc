// SPDX-License-Identifier: Apache-2.0
#include "http_connections.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>

#include "tcp_bytes_received.h"

namespace tessera::server {

namespace {

// The descriptor the last accept() on this thread returned (see the header).
thread_local int t_last_accepted = -1;

// Connections cut past a deadline, over every queue of this process (the log says the total).
std::atomic<uint64_t> g_cut{0};

std::string peer_address(int fd) {
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&ss), &len) != 0) return "?";
  char buf[INET6_ADDRSTRLEN] = "?";
  if (ss.ss_family == AF_INET) {
    ::inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(&ss)->sin_addr, buf, sizeof buf);
  } else if (ss.ss_family == AF_INET6) {
    ::inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(&ss)->sin6_addr, buf, sizeof buf);
  }
  return buf;
}

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

struct HttpConnections::Connection {
  int dup = -1;  // our own descriptor of the socket: shut down through it, closed at the end
  std::string peer;
  std::atomic<bool> handling{false};  // request head read, response not yet written
  std::atomic<int64_t> since{0};      // when the current phase began (steady ns)
  std::atomic<uint64_t> request_from{0};  // bytes received when the current request began
  bool cut = false;                   // guarded by mu_
  std::atomic<bool> close_after{false};  // end it once the answer is written (its thread sets it)
  const HttpConnections* queue = nullptr;
};

namespace {
thread_local HttpConnections::Connection* t_current = nullptr;
}

HttpConnections::HttpConnections(Options options) : options_(options) {
  for (size_t i = 0; i < std::max<size_t>(1, options_.threads); ++i) threads_.emplace_back([this] { run(); });
  watchdog_ = std::thread([this] { watch(); });
}

HttpConnections::~HttpConnections() { shutdown(); }

void HttpConnections::enqueue(std::function<void()> fn) {
  const int fd = std::exchange(t_last_accepted, -1);
  auto c = std::make_shared<Connection>();
  c->since = now_ns();
  c->queue = this;
  if (fd >= 0) {
    c->dup = ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
    c->peer = peer_address(fd);
  }
  std::unique_lock lock(mu_);
  const auto peer = per_peer_.find(c->peer);
  const size_t from_peer = peer == per_peer_.end() ? 0 : peer->second;
  const bool over = fd >= 0 && (live_.size() >= options_.max_connections || from_peer >= options_.max_per_peer);
  if (over || stop_) {
    // The task would close the socket; it will not run, so close it here (and our duplicate).
    const size_t open = live_.size();
    lock.unlock();
    if (c->dup >= 0) ::close(c->dup);
    if (fd >= 0) ::close(fd);
    if (over) {
      spdlog::debug("HTTP: connection from {} closed at once: {} connections open, {} from that address", c->peer,
                    open, from_peer);
    }
    return;
  }
  if (fd >= 0) ++per_peer_[c->peer];
  live_[c.get()] = c;
  queue_.emplace_back(std::move(c), std::move(fn));
  lock.unlock();
  cv_.notify_one();
}

void HttpConnections::shutdown() {
  {
    std::lock_guard lock(mu_);
    if (stop_ && threads_.empty()) return;
    stop_ = true;
    // Running connections end now, not at their client's pace.
    for (auto& [p, c] : live_) {
      if (c->dup >= 0) ::shutdown(c->dup, SHUT_RDWR);
    }
  }
  cv_.notify_all();
  watch_cv_.notify_all();
  for (auto& t : threads_) t.join();
  threads_.clear();
  if (watchdog_.joinable()) watchdog_.join();
}

void HttpConnections::request_read() {
  if (!t_current) return;
  t_current->since = now_ns();
  t_current->handling = true;
}

void HttpConnections::response_written() {
  if (!t_current) return;
  t_current->since = now_ns();
  t_current->request_from = tcp_bytes_received(t_current->dup);
  t_current->handling = false;
  if (t_current->close_after) t_current->queue->linger_close(*t_current);
}

void HttpConnections::close_after_response() {
  if (t_current) t_current->close_after = true;
}

void HttpConnections::linger_close(Connection& c) const {
  if (c.dup < 0) return;
  ::shutdown(c.dup, SHUT_WR);  // the answer, then the end of the stream
  const int64_t end = now_ns() + std::chrono::duration_cast<std::chrono::nanoseconds>(options_.linger).count();
  char drop[16384];
  for (int64_t left; (left = end - now_ns()) > 0;) {
    pollfd p{c.dup, POLLIN, 0};
    if (::poll(&p, 1, int(left / 1000000) + 1) <= 0) break;
    if (::recv(c.dup, drop, sizeof drop, MSG_DONTWAIT) <= 0) break;  // the client closed (or reset)
  }
  ::shutdown(c.dup, SHUT_RDWR);  // cpp-httplib's next read ends the connection
}

void HttpConnections::run() {
  std::unique_lock lock(mu_);
  while (true) {
    cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, and nothing left (queued ones still run: they close their sockets)
    auto [c, fn] = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    t_current = c.get();
    fn();
    t_current = nullptr;
    end(c);
    lock.lock();
  }
}

void HttpConnections::end(const std::shared_ptr<Connection>& c) {
  {
    std::lock_guard lock(mu_);
    live_.erase(c.get());
    if (auto it = per_peer_.find(c->peer); it != per_peer_.end() && --it->second == 0) per_peer_.erase(it);
  }
  if (c->dup >= 0) ::close(c->dup);
}

void HttpConnections::watch() {
  std::unique_lock lock(mu_);
  while (!stop_) {
    watch_cv_.wait_for(lock, options_.tick);
    const int64_t now = now_ns();
    uint64_t cut = 0;
    for (auto& [p, c] : live_) {
      if (c->cut || c->dup < 0 || c->close_after) continue;  // one being closed lingers for a bounded time
      const auto limit = c->handling ? options_.response_deadline : options_.header_deadline;
      const bool late = now - c->since.load() > std::chrono::duration_cast<std::chrono::nanoseconds>(limit).count();
      if (!late && tcp_bytes_received(c->dup) - c->request_from.load() <= options_.max_request_bytes) continue;
      // Under mu_, the duplicate is open: it names this socket and no other.
      ::shutdown(c->dup, SHUT_RDWR);
      c->cut = true;
      ++cut;
    }
    if (cut > 0) {
      g_cut += cut;
      spdlog::warn("HTTP: closed {} connection(s) that did not complete a request within {} s or {} KiB, or answer "
                   "within {} s ({} since start)",
                   cut, options_.header_deadline.count() / 1000.0, options_.max_request_bytes >> 10,
                   options_.response_deadline.count() / 1000.0, g_cut.load());
    }
  }
}

}  // namespace tessera::server

// cpp-httplib's accept (see http_connections.h): the system call, noting the descriptor for the
// enqueue() that follows on this thread. Exported from the executable (server/CMakeLists.txt).
extern "C" int accept(int fd, sockaddr* addr, socklen_t* len) {
  const int r = int(::syscall(SYS_accept4, fd, addr, len, 0));
  if (r >= 0) tessera::server::t_last_accepted = r;
  return r;
}

// SPDX-License-Identifier: Apache-2.0
// relay_floor: what a coordinator in the pixel path pays a tile before any protocol or
// bookkeeping. One thread does only what the coordinator cannot avoid doing with a tile's bytes:
// receive them from a worker's TCP connection, append them to a file made durable in batches
// (fdatasync, as the tile store does), and send them on to a client's TCP connection. A producer
// and a consumer thread play the worker and the client over loopback. It reports the relay
// thread's CPU time a tile (CLOCK_THREAD_CPUTIME_ID), with each tile's bytes held in fresh memory
// until the end (as the coordinator holds a tile until its frame is acknowledged) and with one
// buffer reused (no page faults).
//
// A benchmark, not a test: it asserts nothing about time (docs/performance.md, "The coordinator's
// cost per tile").
#include <CLI/CLI.hpp>
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <nlohmann/json.hpp>
#include <pthread.h>
#include <sched.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const std::string& what) { throw std::runtime_error(what + ": " + std::strerror(errno)); }

void pin(int cpu) {
  if (cpu < 0) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  pthread_setaffinity_np(pthread_self(), sizeof set, &set);
}

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + double(ts.tv_nsec) * 1e-9;
}

void read_all(int fd, char* p, size_t n) {
  while (n > 0) {
    const ssize_t r = ::recv(fd, p, n, 0);
    if (r <= 0) fail("recv");
    p += r;
    n -= size_t(r);
  }
}

void write_all(int fd, const char* p, size_t n, bool socket) {
  while (n > 0) {
    const ssize_t r = socket ? ::send(fd, p, n, MSG_NOSIGNAL) : ::write(fd, p, n);
    if (r <= 0) fail(socket ? "send" : "write");
    p += r;
    n -= size_t(r);
  }
}

// A connected pair of loopback TCP sockets (what a worker's or a client's connection is).
std::pair<int, int> tcp_pair() {
  const int lst = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  if (::bind(lst, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(lst, 1) != 0 ||
      ::getsockname(lst, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    fail("listen");
  }
  const int c = ::socket(AF_INET, SOCK_STREAM, 0);
  if (::connect(c, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) fail("connect");
  const int s = ::accept(lst, nullptr, nullptr);
  if (s < 0) fail("accept");
  ::close(lst);
  const int one = 1;
  for (int fd : {c, s}) ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return {c, s};
}

struct Result {
  double us_per_tile = 0;
  double seconds = 0;
};

Result run(int tiles, size_t bytes, int batch, int sync_every, bool fresh, int relay_cpu, int peer_cpu,
           const fs::path& dir) {
  tiles -= tiles % batch;
  const size_t chunk = bytes * size_t(batch);  // a message of `batch` tiles, as a worker's batched results
  auto [worker, relay_in] = tcp_pair();
  auto [relay_out, client] = tcp_pair();
  const fs::path file = dir / "relay_floor.seg";
  const int out = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (out < 0) fail("open " + file.string());
  std::thread producer([&, worker = worker] {
    pin(peer_cpu);
    std::vector<char> tile(chunk, 'x');
    for (int i = 0; i < tiles; i += batch) write_all(worker, tile.data(), chunk, true);
  });
  std::thread consumer([&, client = client] {
    pin(peer_cpu);
    std::vector<char> sink(chunk);
    for (int i = 0; i < tiles; i += batch) read_all(client, sink.data(), chunk);
  });
  Result r;
  std::thread relay([&, relay_in = relay_in, relay_out = relay_out] {
    pin(relay_cpu);
    std::vector<std::unique_ptr<char[]>> held;
    std::unique_ptr<char[]> reused(new char[chunk]);
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = thread_cpu_seconds();
    int unsynced = 0;
    for (int i = 0; i < tiles; i += batch) {
      char* p = reused.get();
      if (fresh) {
        held.emplace_back(new char[chunk]);
        p = held.back().get();
      }
      read_all(relay_in, p, chunk);
      write_all(out, p, chunk, false);
      if ((unsynced += batch) >= sync_every) {
        if (::fdatasync(out) != 0) fail("fdatasync");
        unsynced = 0;
      }
      write_all(relay_out, p, chunk, true);
    }
    r.us_per_tile = (thread_cpu_seconds() - c0) / tiles * 1e6;
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  });
  producer.join();
  relay.join();
  consumer.join();
  for (int fd : {worker, relay_in, relay_out, client, out}) ::close(fd);
  fs::remove(file);
  return r;
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"relay_floor: a coordinator's unavoidable cost a tile: receive, durable append, send"};
  int tiles = 20000, tile_px = 32, batch = 16, bytes_per_px = 14, sync_every = 64, relay_cpu = -1, peer_cpu = -1,
      repeat = 3;
  std::string dir = fs::temp_directory_path().string(), json_out;
  app.add_option("--tiles", tiles, "Tiles relayed a run")->check(CLI::Range(100, 10000000))->capture_default_str();
  app.add_option("--tile", tile_px, "Tile size in pixels")->check(CLI::Range(1, 1024))->capture_default_str();
  app.add_option("--bytes-per-pixel", bytes_per_px, "A tile's bytes a pixel (14: float RGB, bfloat16 variance)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--batch", batch, "Tiles a message and a write (a worker's batch of results)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--sync-every", sync_every, "Tiles per fdatasync (the store's batch)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--relay-cpu", relay_cpu, "Pin the relay thread to this CPU (-1: any)")->capture_default_str();
  app.add_option("--peer-cpu", peer_cpu, "Pin the producer and consumer to this CPU (-1: any)")->capture_default_str();
  app.add_option("--dir", dir, "Directory of the appended file (the coordinator's data directory's disk)")
      ->check(CLI::ExistingDirectory)
      ->capture_default_str();
  app.add_option("--repeat", repeat, "Runs of each mode")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_option("--json", json_out, "Write the JSON results here (default: stdout, after the table)");
  CLI11_PARSE(app, argc, argv);

  const size_t bytes = size_t(tile_px) * size_t(tile_px) * size_t(bytes_per_px);
  nlohmann::json j{{"benchmark", "relay_floor"},
                   {"cpu", cpu_model()},
                   {"cores", std::thread::hardware_concurrency()},
                   {"tiles", tiles},
                   {"tile", tile_px},
                   {"bytes_per_tile", bytes},
                   {"sync_every", sync_every},
                   {"batch", batch},
                   {"relay_cpu", relay_cpu},
                   {"peer_cpu", peer_cpu}};
  std::printf("%s, %zu B a tile (%d px, %d B a pixel), %d tiles a message, fdatasync every %d tiles\n\n",
              cpu_model().c_str(), bytes, tile_px, bytes_per_px, batch, sync_every);
  std::printf("| tile memory | relay CPU µs a tile (runs) | MB/s relayed a relay core |\n|---|---|---:|\n");
  try {
    for (bool fresh : {true, false}) {
      std::vector<double> us;
      for (int i = 0; i < repeat; ++i)
        us.push_back(run(tiles, bytes, batch, sync_every, fresh, relay_cpu, peer_cpu, dir).us_per_tile);
      std::vector<double> sorted = us;
      std::sort(sorted.begin(), sorted.end());
      const double median = sorted[sorted.size() / 2];
      std::string runs;
      for (double u : us) runs += (runs.empty() ? "" : ", ") + std::to_string(int(u * 10 + 0.5) / 10.0).substr(0, 5);
      std::printf("| %s | %.1f (%s) | %.0f |\n", fresh ? "fresh, held (as the coordinator)" : "one buffer reused",
                  median, runs.c_str(), double(bytes) / median);
      j[fresh ? "fresh_held" : "reused"] = {{"us_per_tile", us}, {"median_us_per_tile", median}};
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "relay_floor: %s\n", e.what());
    return 1;
  }
  if (json_out.empty()) {
    std::cout << "\n" << j.dump(2) << "\n";
  } else {
    std::ofstream(json_out) << j.dump(2) << "\n";
  }
  return 0;
}

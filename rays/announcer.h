// SPDX-License-Identifier: Apache-2.0
// tessera-rays telling the coordinator where it is (WorkerService.AnnounceRayServer, worker
// token): at start, then every period, so `tessera rayservers` lists it and `tessera rays
// --coordinator` (without --server) finds it. The coordinator forgets a server that stays silent
// for 3 periods (server/ray_servers.h).
//
// The service never depends on it: a coordinator that is down, refuses the token or predates
// the RPC costs a log line (repeated only when the problem changes) and retries with backoff up
// to the period, while clients that name the server with --server are answered as before.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "tessera/v1/worker_service.grpc.pb.h"

namespace tessera::rayserver {

class Announcer {
 public:
  // `describe` is called before each announcement (the counters move). `coordinator` names the
  // coordinator in messages. The thread starts here and announces at once.
  Announcer(tessera::v1::WorkerService::Stub& stub, std::string coordinator, std::chrono::milliseconds period,
            std::function<tessera::v1::RayServerDescription()> describe);
  // Stops the thread and tells the coordinator this server is leaving (one try, 1 s), so clients
  // stop picking it at once rather than after the expiry.
  ~Announcer();
  Announcer(const Announcer&) = delete;
  Announcer& operator=(const Announcer&) = delete;

 private:
  void loop();
  // Announces once; on success `*period` becomes the coordinator's. The problem, or "".
  std::string announce_once(std::chrono::milliseconds* period, int* expiry_ms, bool leaving = false);

  tessera::v1::WorkerService::Stub& stub_;
  std::string coordinator_;
  std::chrono::milliseconds period_;
  std::function<tessera::v1::RayServerDescription()> describe_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  bool listed_ = false;  // the last announcement was accepted (read after the thread ended)
  std::thread thread_;
};

// The address announced to clients: --advertise (HOST:PORT, or HOST to use the bound port), else
// the --listen host with the bound port. Throws std::invalid_argument when --listen is a wildcard
// (0.0.0.0, [::]) and --advertise is not given: no client can dial a wildcard, and guessing one
// of the machine's addresses would list a server at an address that may not reach it.
std::string advertised_address(const std::string& listen, const std::string& advertise, int port);

// A random id for this run of the server (16 hex digits).
std::string new_server_id();

}  // namespace tessera::rayserver

// SPDX-License-Identifier: Apache-2.0
// What the coordinator's HTTP side reads of it: the web monitor (server/monitor) and the
// Prometheus metrics (server/metrics) look at the farm, they do not run it. A snapshot of the
// whole farm, a job's status and finished tiles, the ray servers, the bundle traffic, and the
// scheduler's events as they happen. The Coordinator implements it; the monitor and the metrics
// include this header, not coordinator.h, so they see neither its streams nor its job store
// (SQLite) nor the worker protocol.
#pragma once

#include <grpcpp/support/status.h>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "job_store_stats.h"
#include "scheduler.h"
#include "tessera/v1/client_service.pb.h"

namespace tessera::server {

// What the coordinator knows at one instant, for observers that look rather than act (the web
// monitor, the Prometheus gauges). Taken under the coordinator's mutex, used after it.
struct FarmSnapshot {
  std::vector<JobSnapshot> jobs;      // in memory, in submit order
  std::vector<WorkerStats> workers;
  size_t tiles_queued = 0;
  size_t watch_backlog = 0;           // messages queued and unwritten over every watch stream
  tessera::v1::DeliveryBacklog delivery;  // finished frames of jobs with an output, not yet delivered
  JobStoreStats store;                // zero without a job store
};

class FarmView {
 public:
  virtual ~FarmView() = default;

  // `observer` receives every scheduler event after the coordinator handled it, under the
  // coordinator's mutex: it must be quick and must not call back into the coordinator. Add
  // observers before any stream starts. An observer removes itself before it is destroyed
  // (remove_observer: no event reaches it once that returns).
  virtual void add_observer(SchedulerListener* observer) = 0;
  virtual void remove_observer(SchedulerListener* observer) = 0;
  virtual FarmSnapshot snapshot() = 0;
  // Every finished tile of the job still in memory (frames not yet acknowledged).
  virtual std::vector<std::pair<TileKey, TileOutput>> finished_tiles(const std::string& id) = 0;
  // A job's status, in memory or evicted from it (read from the job store): NOT_FOUND for an
  // unknown job.
  virtual grpc::Status get_job(const std::string& id, tessera::v1::JobStatus* out) = 0;
  // The identity that submitted the job (JobSpec::owner; "" for jobs of older databases), in
  // memory or evicted; nullopt for an unknown job.
  virtual std::optional<std::string> job_owner(const std::string& id) = 0;
  // A snapshot's job as its status message.
  virtual void status_of(const JobSnapshot& s, tessera::v1::JobStatus* out) const = 0;
  // The tessera-rays servers announced and not expired: listed, and counted.
  virtual void list_ray_servers(tessera::v1::ListRayServersResponse* out) = 0;
  virtual size_t live_ray_servers() = 0;
  // Bytes of new scene bundles stored, and of bundles sent to workers, since start.
  virtual uint64_t bundle_bytes_stored() const = 0;
  virtual uint64_t bundle_bytes_served() const = 0;
};

}  // namespace tessera::server

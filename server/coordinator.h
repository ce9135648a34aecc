// SPDX-License-Identifier: Apache-2.0
// The coordinator's shared state: the Scheduler behind one mutex, the bundle store, and the open
// streams (worker sessions, job watchers). The gRPC services are thin adapters onto this class.
//
// Locking: `mu_` guards the scheduler and the stream registries. Scheduler events (the
// SchedulerListener methods) run under `mu_` and only queue messages into outboxes; the queued
// outboxes are pumped after `mu_` is released (see stream_outbox.h for why). Every public entry
// point goes through locked() (defined at the end of this header), which does exactly that.
//
// The member functions are defined by concept, one file each:
//   coordinator.cpp           lifetime: restore from the job store, the expiry thread, eviction,
//                             observers and snapshots
//   coordinator_jobs.cpp      the job API: submit, status, cancel, priority, frame acknowledgement
//   coordinator_watchers.cpp  watch streams: attach, detach, flow control of slow clients
//   coordinator_workers.cpp   worker sessions: registration, messages, results, dispatch
//   scheduler_events.cpp      the SchedulerListener: log, persist, notify streams and observers
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "bundle_store.h"
#include "coordinator_messages.h"
#include "delivery_leases.h"
#include "farm_control.h"
#include "frame_passes.h"
#include "job_store.h"
#include "peer_warnings.h"
#include "ray_servers.h"
#include "scheduler.h"
#include "scene/scene.h"
#include "stream_sink.h"
#include "undelivered_frames.h"
#include "tessera/v1/client_service.pb.h"
#include "tessera/v1/worker_service.pb.h"

namespace tessera::server {

using WorkerSink = StreamSink<tessera::v1::CoordinatorMessage>;
using WatchSink = StreamSink<tessera::v1::WatchJobEvent>;

struct CoordinatorOptions {
  SchedulerOptions scheduler;
  std::chrono::milliseconds heartbeat_interval{1000};
  std::chrono::milliseconds expiry_check{200};
  // Ended jobs leave memory once a client acknowledged every frame, or this long after they
  // ended (they stay in SQLite: `tessera status JOB` still answers).
  std::chrono::seconds retention{std::chrono::hours(24)};
  // Flow control of watch streams: when one of a job's watch streams has this many messages
  // queued and unwritten (the client reads slower than the farm renders), the job is held (no
  // new leases; leases in flight finish) until that stream is down to half of it. This bounds
  // the finished tiles the coordinator keeps in memory for a job to about this many plus the
  // tiles in flight and the unacknowledged frames. 0: no bound. Unwatched jobs are not held:
  // their tiles are durable and a client attaching later gets them in one go.
  size_t watch_backlog_tiles = 2048;
  // The largest message the gRPC server receives, told to workers so that their result batches
  // stay under it (0: not said).
  int64_t max_message_bytes = 0;
  // Tiles of all jobs in memory together (farm::Limits::max_resident_tiles), and of one job
  // (max_job_tiles; a frame over it is refused at submit by the Admission): the scheduler holds
  // them to it (SchedulerOptions), and a stored job whose one frame cannot fit under them is not
  // restored but failed, by name. 0: no limit.
  int64_t max_resident_tiles = 0;
  int64_t max_job_tiles = 0;
  // Delivery (docs/farm.md, "Delivery"): a deliverer that was sent a whole frame and has not
  // acknowledged it this long after loses it to another deliverer of the job, if there is one.
  std::chrono::milliseconds delivery_lease{std::chrono::minutes(2)};
  // Finished frames of jobs with a recorded output are kept until delivered, past `retention`; new
  // jobs are refused once their encoded bytes reach this. 0: no limit.
  uint64_t max_undelivered_bytes = 0;
};

// What a submission must satisfy besides naming a valid scene, and whose it is. The scene is
// parsed once, by Coordinator::submit, with these limits and confined to its bundle.
struct Admission {
  std::string owner;            // the client identity the job counts against (stored with the job)
  uint64_t max_primitives = 0;  // checked while loading (SceneLoadOptions); 0: no limit
  uint64_t max_texture_pixels = 0;  // the same, for glTF texture pixels; 0: SceneLoadOptions' default
  // The request limits that need the parsed scene (resolution, spp, frames, tiles of `tile` px);
  // may be empty.
  std::function<grpc::Status(const Scene&, int first_frame, int last_frame, int tile)> check;
};

// What the web monitor and the metrics read of it, and the changes the monitor makes: FarmControl
// (farm_view.h, farm_control.h).
class Coordinator : private SchedulerListener, public FarmControl {
 public:
  // `jobs` (may be null: memory only, for tests) is loaded and restored here, before any stream.
  Coordinator(CoordinatorOptions options, BundleStore& store, JobStore* jobs = nullptr);
  ~Coordinator() override;
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  BundleStore& bundles() { return store_; }
  // The tessera-rays servers announced to this coordinator: their own lock, nothing to do with
  // scheduling (liveness only, in memory: ray_servers.h).
  RayServers& ray_servers() { return ray_servers_; }

  // --- client service -----------------------------------------------------------------------
  grpc::Status submit(const tessera::v1::SubmitJobRequest& req, tessera::v1::JobStatus* out,
                      const Admission& admission = {});
  // (owner, job id) of every queued or running job with an owner: the quota after a restart.
  std::vector<std::pair<std::string, std::string>> active_jobs_by_owner();
  grpc::Status get_job(const std::string& id, tessera::v1::JobStatus* out) override;
  // The identity that submitted the job (JobSpec::owner; "" for jobs of older databases), in
  // memory or evicted; nullopt for an unknown job.
  std::optional<std::string> job_owner(const std::string& id) override;
  // Every job in memory, and the delivery backlog.
  void list_jobs(tessera::v1::ListJobsResponse* out);
  grpc::Status cancel(const std::string& id, tessera::v1::JobStatus* out, bool discard_undelivered = false) override;
  grpc::Status ack_frame(const std::string& id, int frame);
  void list_workers(tessera::v1::ListWorkersResponse* out);
  // NOT_FOUND for an unknown job (also one evicted from memory), FAILED_PRECONDITION for an
  // ended one. The new priority is stored with the job.
  grpc::Status set_priority(const std::string& id, int priority, tessera::v1::JobStatus* out) override;
  // Queues the job's status and every unacknowledged finished tile into `sink`, then keeps it
  // attached for new tiles until the job ends. NOT_FOUND for an unknown job.
  // `deliver`: the stream writes frames and acknowledges them (WatchJobRequest.deliver_frames): it
  // gets only the frames it holds a delivery lease on, and stays attached after the job ended
  // until every finished frame is acknowledged.
  grpc::Status attach_watcher(const std::string& id, std::shared_ptr<WatchSink> sink, bool deliver = false);
  void detach_watcher(const std::shared_ptr<WatchSink>& sink);
  // A throttled watch stream is down to half its backlog bound: release its job if no other
  // stream of it is still behind. Called by the stream, without locks.
  void watcher_drained(const std::shared_ptr<WatchSink>& sink);
  size_t watch_low_water() const { return options_.watch_backlog_tiles / 2; }

  // --- worker service -----------------------------------------------------------------------
  // `reads_batches`: the worker reads several assignments in one message (Register).
  WorkerId register_worker(const WorkerInfo& info, std::shared_ptr<WorkerSink> sink, bool reads_batches = false);
  void worker_gone(WorkerId id, std::string_view reason);
  // Takes the pixel bytes out of `msg` (no copy): the caller reads the next message into it.
  void worker_message(WorkerId id, tessera::v1::WorkerMessage& msg);

  // --- observers (the Prometheus metrics, the web monitor) ---------------------------------
  // `observer` receives every scheduler event after the coordinator handled it, under the
  // coordinator's mutex: it must be quick and must not call back into the coordinator. Add
  // observers before any stream starts. An observer removes itself before it is destroyed
  // (remove_observer: no event reaches it once that returns), so it may go before or after the
  // coordinator's streams.
  void add_observer(SchedulerListener* observer) override;
  void remove_observer(SchedulerListener* observer) override;
  FarmSnapshot snapshot() override;
  // Every finished tile of the job still in memory (frames not yet acknowledged).
  std::vector<std::pair<TileKey, TileOutput>> finished_tiles(const std::string& id) override;
  void status_of(const JobSnapshot& s, tessera::v1::JobStatus* out) const override { job_status_proto(s, out); }
  void list_ray_servers(tessera::v1::ListRayServersResponse* out) override { ray_servers_.list(out); }
  size_t live_ray_servers() override { return ray_servers_.live(); }
  uint64_t bundle_bytes_stored() const override { return store_.bytes_stored(); }
  uint64_t bundle_bytes_served() const override { return store_.bytes_served(); }

  // Stops the expiry thread (before the gRPC server shuts down).
  void stop();

 private:
  // SchedulerListener: runs under mu_.
  void job_submitted(const JobSnapshot&) override;
  void job_state_changed(const JobId&, JobState) override;
  void job_priority_changed(const JobId&, int priority) override;
  void tile_leased(const Assignment&) override;
  void lease_ended(const Lease&, LeaseEnd) override;
  void span_tile_lost(const Lease&, int tile) override;
  void tile_finished(const TileKey&, const TileOutput&, WorkerId) override;
  void frame_finished(const JobId&, int frame) override;
  void frame_acknowledged(const JobId&, int frame) override;
  void worker_joined(const WorkerStats&) override;
  void worker_left(const WorkerStats&, std::string_view reason) override;
  void worker_faulted(const JobId&, const WorkerStats&, std::string_view reason, int faults, bool blocklisted) override;

  // Runs `f` under mu_, then pumps every outbox it touched.
  template <class F>
  auto locked(F&& f);
  void dispatch_locked();
  void tile_result_locked(WorkerId id, tessera::v1::TileResult& r);
  void expiry_loop();
  void restore_locked();
  // A stored job whose tiles do not fit under the limits: failed and left in the database, by
  // name, instead of built (true); false to restore it.
  bool refuse_restore_locked(const JobRecord& r);
  void evict_locked(const JobId& id, const char* why);
  // `s`, once everything the call queued in the job store is committed; UNAVAILABLE saying
  // "<what> but cannot be stored right now" when that fails. Called without mu_ held.
  grpc::Status durable(grpc::Status s, const std::string& what);
  void evict_expired_locked();
  std::optional<JobSnapshot> evicted_job(const std::string& id);  // without mu_
  grpc::Status attach_resident(const std::string& id, const std::shared_ptr<WatchSink>& sink, bool deliver);
  // Delivery (coordinator_delivery.cpp). The frame's finished tiles, and its frame_done when it is
  // final, into the stream that holds its delivery lease.
  void send_frame_locked(const JobId& job, const std::shared_ptr<WatchSink>& sink, int frame);
  std::shared_ptr<WatchSink> watcher_locked(const JobId& job, DeliveryLeases::Deliverer d) const;
  // Frames held by nobody (their deliverer went, or overdue) go to another deliverer of the job.
  void reassign_frames_locked(const JobId& job, const std::vector<int>& frames);
  void expire_deliveries_locked();
  // A finished tile / frame, to the spectators and to the frame's deliverer.
  void route_tile_locked(const TileKey& key, const TileOutput& out);
  void route_frame_done_locked(const JobId& job, int frame);
  // The final status into the job's streams, and their end: spectators when the job ends,
  // deliverers once no finished frame waits for delivery (`all`: every stream, the job leaves).
  void finish_watchers_locked(const JobId& job, bool all);
  bool delivered_locked(const JobId& job) const;  // ended, every finished frame acknowledged
  void frame_undelivered_locked(const JobId& job, int frame, TimePoint finished);
  tessera::v1::DeliveryBacklog delivery_backlog_locked() const;
  grpc::Status undelivered_limit_locked() const;
  grpc::Status set_priority_resident(const std::string& id, int priority, tessera::v1::JobStatus* out);
  // Queues a finished tile into a watch stream (shared encoded bytes, parsed when written) and
  // holds the job when that stream's backlog reaches the bound.
  void push_tile_locked(const JobId& job, const std::shared_ptr<WatchSink>& sink,
                        const std::shared_ptr<const std::string>& payload);
  // Releases a held job once none of its streams is throttled.
  void release_if_caught_up_locked(const JobId& job);

  CoordinatorOptions options_;
  BundleStore& store_;
  JobStore* jobs_store_;
  RayServers ray_servers_;
  std::mutex mu_;
  Scheduler scheduler_;
  FramePasses passes_;  // frame-target jobs' frames between passes
  struct WorkerStream {
    std::shared_ptr<WorkerSink> sink;
    bool reads_batches = false;  // Register.reads_assignment_batches
  };
  std::map<WorkerId, WorkerStream> workers_;
  std::multimap<JobId, std::shared_ptr<WatchSink>> watchers_;
  DeliveryLeases deliveries_;       // which deliverer stream writes which finished frame
  UndeliveredFrames undelivered_;   // finished frames of jobs with an output, not yet delivered
  std::set<JobId> kept_for_delivery_;  // past retention, kept for their undelivered frames (logged once)
  std::map<JobId, TimePoint> ended_;  // ended jobs still in memory (retention)
  std::map<JobId, TimePoint> awaiting_first_tile_;  // submit time, until the first tile (logged)
  PeerWarnings peer_warnings_;  // what workers sent wrong, one line a second each
  std::set<std::string> isas_;  // Embree ISAs seen: bit-identity needs the same kernels
  std::vector<std::shared_ptr<WorkerSink>> touched_workers_;
  std::vector<std::shared_ptr<WatchSink>> touched_watchers_;
  std::vector<SchedulerListener*> observers_;
  // Calls `event` on every observer (under mu_).
  template <class F>
  void notify(F&& event) {
    for (SchedulerListener* o : observers_) event(*o);
  }

  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
  std::thread expiry_;
};

template <class F>
auto Coordinator::locked(F&& f) {
  std::vector<std::shared_ptr<WorkerSink>> workers;
  std::vector<std::shared_ptr<WatchSink>> watchers;
  auto pump = [&] {
    for (auto& w : workers) w->pump();
    for (auto& w : watchers) w->pump();
  };
  std::unique_lock lock(mu_);
  if constexpr (std::is_void_v<decltype(f())>) {
    f();
    workers.swap(touched_workers_);
    watchers.swap(touched_watchers_);
    lock.unlock();
    pump();
  } else {
    auto result = f();
    workers.swap(touched_workers_);
    watchers.swap(touched_watchers_);
    lock.unlock();
    pump();
    return result;
  }
}

}  // namespace tessera::server

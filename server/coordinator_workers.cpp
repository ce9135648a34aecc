// SPDX-License-Identifier: Apache-2.0
// Worker sessions: registration, the messages a worker sends (tile requests, results, returned
// and failed leases), the checks a result must pass before it counts, and dispatch: the leases the
// scheduler hands out, sent to their workers.
#include "coordinator.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "farm/peer_text.h"
#include "farm/tile_codec.h"
#include "result_bounds.h"
#include "sampling/pass_plan.h"

namespace tessera::server {

namespace v1 = tessera::v1;

WorkerId Coordinator::register_worker(const WorkerInfo& info, std::shared_ptr<WorkerSink> sink, bool reads_batches) {
  return locked([&] {
    const WorkerId id = scheduler_.add_worker(info);
    workers_[id] = WorkerStream{sink, reads_batches};
    v1::CoordinatorMessage m;
    m.mutable_welcome()->set_worker_id(std::to_string(id));
    m.mutable_welcome()->set_heartbeat_interval_ms(int(options_.heartbeat_interval.count()));
    m.mutable_welcome()->set_lease_timeout_ms(int(options_.scheduler.lease_timeout.count()));
    m.mutable_welcome()->set_reads_request_more(true);
    m.mutable_welcome()->set_reads_result_batches(true);
    m.mutable_welcome()->set_max_message_bytes(options_.max_message_bytes);
    sink->push(m);
    touched_workers_.push_back(sink);
    return id;
  });
}

void Coordinator::worker_gone(WorkerId id, std::string_view reason) {
  locked([&] {
    scheduler_.remove_worker(id, reason);
    workers_.erase(id);
    dispatch_locked();
  });
}

void Coordinator::worker_message(WorkerId id, v1::WorkerMessage& msg) {
  locked([&] {
    scheduler_.heartbeat(id);  // any message is a sign of life
    switch (msg.msg_case()) {
      case v1::WorkerMessage::kRequest:
        scheduler_.request_tiles(id, msg.request().count());
        break;
      case v1::WorkerMessage::kResult:
        tile_result_locked(id, *msg.mutable_result());
        if (msg.result().request_more() > 0) scheduler_.request_tiles(id, msg.result().request_more());
        break;
      case v1::WorkerMessage::kResults: {
        // Each result counts exactly as if it had come alone; the requests add up (in 64 bits:
        // the scheduler caps a worker's standing request, a sum of int32s must not wrap first).
        int64_t more = std::max(0, msg.results().request_more());
        for (v1::TileResult& r : *msg.mutable_results()->mutable_results()) {
          tile_result_locked(id, r);
          more += std::max(0, r.request_more());
        }
        if (more > 0) scheduler_.request_tiles(id, int(std::min<int64_t>(more, 1 << 30)));
        break;
      }
      case v1::WorkerMessage::kReturned: {
        scheduler_.return_leases(id, {msg.returned().lease_ids().begin(), msg.returned().lease_ids().end()});
        std::vector<std::pair<LeaseId, int>> tiles;
        for (const v1::LeaseTile& t : msg.returned().tiles()) tiles.emplace_back(t.lease_id(), t.tile_index());
        if (!tiles.empty()) scheduler_.return_tiles(id, tiles);
        break;
      }
      case v1::WorkerMessage::kFailed: {
        auto lease = scheduler_.lease(msg.failed().lease_id());
        if (!lease || lease->worker != id) break;  // revoked meanwhile: nothing to count
        // The reason is stored with the job and shown to every client: bounded, one line.
        scheduler_.fault(id, lease->tile.job, lease->id,
                         fmt::format("frame {} tile {}: worker cannot render: {}", lease->tile.frame, lease->tile.tile,
                                     farm::peer_text(msg.failed().reason(), farm::kMaxReasonBytes)));
        break;
      }
      default:
        break;
    }
    dispatch_locked();
  });
}

void Coordinator::tile_result_locked(WorkerId id, v1::TileResult& r) {
  auto lease = scheduler_.lease(r.lease_id());
  if (!lease || lease->worker != id) {
    // A lease this worker held and lost (revoked, expired, from before a restart) is normal
    // traffic. A lease id never issued, or another worker's live lease, is a lie: a fault.
    const bool never_issued = r.lease_id() == 0 || r.lease_id() >= scheduler_.next_lease();
    if (!never_issued && !lease) {
      spdlog::debug("worker {}: result for lease {} ignored (revoked, expired or from before a restart)", id,
                    r.lease_id());
      return;
    }
    const std::string why = never_issued
                                ? fmt::format("stale lease {}: never issued by this coordinator", r.lease_id())
                                : fmt::format("lease {} belongs to worker {}", r.lease_id(), lease->worker);
    if (scheduler_.fault(id, r.tile().job_id(), std::nullopt,
                         fmt::format("frame {} tile {}: {}", r.tile().frame(), r.tile().tile_index(), why)) == 0) {
      // No job to blocklist the worker for: counted against the session, logged a line a second.
      scheduler_.count_refused(id);
      peer_warnings_.warn(id, "worker {}: refused a result for unknown job '{}': {}", id,
                          farm::peer_text(r.tile().job_id(), 80), why);
    }
    return;
  }
  if (r.tile().job_id() != lease->tile.job || r.tile().frame() != lease->tile.frame ||
      !lease->covers(r.tile().tile_index())) {
    // An honest worker echoes its assignment: a result that names another job, frame or tile
    // than its lease's is a fault, never relabelled (its pixels are of whatever it names).
    scheduler_.fault(id, lease->tile.job, lease->id,
                     fmt::format("frame {} tile {}: the result names job '{}' frame {} tile {}, not its lease's",
                                 lease->tile.frame, lease->tile.tile, farm::peer_text(r.tile().job_id(), 80),
                                 r.tile().frame(), r.tile().tile_index()));
    return;
  }
  const int tile_index = r.tile().tile_index();  // one of the lease's tiles (checked above)
  if (!lease->is_pending(tile_index)) {
    // A tile of its span that another copy finished first (the worker was told to drop it), or
    // a second result for one tile: nothing to check or count.
    spdlog::debug("worker {}: result for lease {} tile {} ignored (finished by another copy)", id, r.lease_id(),
                  tile_index);
    return;
  }
  const auto rect = scheduler_.tile_rect(lease->tile.job, lease->tile.frame, tile_index);
  const JobSpec& spec = scheduler_.header(lease->tile.job)->spec;
  std::string err = farm::validate_tile(r.tile(), *rect);
  if (err.empty()) {
    err = check_result_bounds(r.tile(), {std::chrono::duration<double>(Clock::now() - lease->issued).count(),
                                         int64_t(rect->width) * rect->height, spec.spp});
  }
  if (err.empty() && spec.passes) {
    // A frame target's pass is planned from the statistics every tile carries: a tile without
    // them (a worker that renders no frame targets) or with malformed ones is a fault now, at
    // the tile, rather than a failed plan at the frame's end.
    std::vector<BlockStat> stats;
    err = farm::decode_block_stats(r.tile().block_stats(), &stats);
    const int expected = BlockGrid(spec.width, spec.height).origins_in(*rect);
    if (err.empty() && int(stats.size()) != expected) {
      err = fmt::format("tile carries {} block statistics, expected {} (frame targets need them)", stats.size(),
                        expected);
    }
  }
  if (!err.empty()) {
    scheduler_.fault(id, lease->tile.job, lease->id,
                     fmt::format("frame {} tile {}: {}", lease->tile.frame, tile_index, err));
    return;
  }
  // What is stored and forwarded is rebuilt from the fields a tile has, the pixel bytes moved, not
  // copied: unknown fields (a worker's padding) go no further, so a stored tile is never larger
  // than its pixels and what identifies it. The coordinator is the authority on what the tile
  // is: it sets the identifying fields.
  v1::TileData tile = farm::known_fields_only(std::move(*r.mutable_tile()));
  tile.set_job_id(lease->tile.job);
  tile.set_frame(lease->tile.frame);
  tile.set_tile_index(tile_index);
  if (auto w = scheduler_.worker(id)) tile.set_worker(w->info.name);
  TileOutput out;
  out.rays = tile.rays().camera() + tile.rays().shadow() + tile.rays().secondary();
  out.seconds = tile.seconds();
  out.payload = std::make_shared<const std::string>(tile.SerializeAsString());
  const auto outcome = scheduler_.complete(id, r.lease_id(), tile_index, std::move(out));
  // One line per result received: tests count re-rendered tiles from these.
  spdlog::debug("result: lease {} job {} frame {} tile {} from worker {}: {}", r.lease_id(), lease->tile.job,
                lease->tile.frame, tile_index, id,
                outcome == Scheduler::ResultOutcome::kAccepted ? "accepted" : "duplicate");
}

void Coordinator::dispatch_locked() {
  // A worker that reads batches gets every lease of this dispatch in one message: the cost of a
  // message is paid once for all of them (a worker asks for several tiles with each batch of
  // results it sends). Dispatch goes round the wanting workers one lease at a time; a stable sort
  // by worker keeps each worker's leases in the order they were made.
  std::vector<Assignment> assignments = scheduler_.dispatch();
  std::stable_sort(assignments.begin(), assignments.end(),
                   [](const Assignment& x, const Assignment& y) { return x.lease.worker < y.lease.worker; });
  v1::CoordinatorMessage batch;
  WorkerStream* batch_to = nullptr;
  const auto send_batch = [&] {
    if (!batch_to) return;
    batch_to->sink->push(std::move(batch));
    touched_workers_.push_back(batch_to->sink);
    batch.Clear();
    batch_to = nullptr;
  };
  for (const Assignment& a : assignments) {
    auto it = workers_.find(a.lease.worker);
    if (it == workers_.end()) continue;
    WorkerStream& w = it->second;
    if (!w.reads_batches) {
      w.sink->push(assignment_message(a));
      touched_workers_.push_back(w.sink);
      continue;
    }
    if (batch_to != &w) send_batch();
    batch_to = &w;
    assignment_proto(a, batch.mutable_assignments()->add_assignments());
  }
  send_batch();
}

void Coordinator::list_workers(v1::ListWorkersResponse* out) {
  locked([&] {
    for (const auto& w : scheduler_.workers()) worker_proto(w, out->add_workers());
  });
}

}  // namespace tessera::server

// Worker sessions: registration, the messages a worker sends (tile requests, results, returned
// and failed leases), the checks a result must pass before it counts, and dispatch: the leases the
// scheduler hands out, sent to their workers.
#include "coordinator.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstring>

#include "farm/codec.h"

namespace tessera::server {

namespace v1 = tessera::v1;

namespace {

// Index of the first NaN or infinite float in little-endian float32 bytes, or -1.
int64_t first_nonfinite(const std::string& bytes) {
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  for (size_t i = 0; i + 4 <= bytes.size(); i += 4) {
    const uint32_t bits = uint32_t(p[i]) | uint32_t(p[i + 1]) << 8 | uint32_t(p[i + 2]) << 16 | uint32_t(p[i + 3]) << 24;
    if ((bits & 0x7f800000u) == 0x7f800000u) return int64_t(i / 4);
  }
  return -1;
}

// Why a tile sent for `rect` cannot be accepted, or "": the wrong size or place, or a pixel value
// or variance that is not finite.
std::string tile_error(const v1::TileData& tile, const Rect& rect) {
  std::string err = farm::check_tile(tile, rect.width, rect.height);
  if (!err.empty()) return err;
  if (tile.rect().x0() != rect.x0 || tile.rect().y0() != rect.y0) {
    return fmt::format("tile at ({}, {}), expected ({}, {})", tile.rect().x0(), tile.rect().y0(), rect.x0, rect.y0);
  }
  if (const int64_t i = first_nonfinite(tile.rgb()); i >= 0) {
    const float v = [&] {
      float f;
      std::memcpy(&f, tile.rgb().data() + i * 4, 4);
      return f;
    }();
    return fmt::format("pixel ({}, {}) channel {} is {}", rect.x0 + (i / 3) % rect.width, rect.y0 + (i / 3) / rect.width,
                       i % 3, std::isnan(v) ? "NaN" : "infinite");
  }
  if (const int64_t j = first_nonfinite(tile.variance()); j >= 0) {
    return fmt::format("variance of pixel ({}, {}) is not finite", rect.x0 + j % rect.width,
                       rect.y0 + j / rect.width);
  }
  return {};
}
}  // namespace

WorkerId Coordinator::register_worker(const WorkerInfo& info, std::shared_ptr<WorkerSink> sink) {
  return locked([&] {
    const WorkerId id = scheduler_.add_worker(info);
    workers_[id] = sink;
    v1::CoordinatorMessage m;
    m.mutable_welcome()->set_worker_id(std::to_string(id));
    m.mutable_welcome()->set_heartbeat_interval_ms(int(options_.heartbeat_interval.count()));
    m.mutable_welcome()->set_lease_timeout_ms(int(options_.scheduler.lease_timeout.count()));
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

void Coordinator::worker_message(WorkerId id, const v1::WorkerMessage& msg) {
  locked([&] {
    scheduler_.heartbeat(id);  // any message is a sign of life
    switch (msg.msg_case()) {
      case v1::WorkerMessage::kRequest:
        scheduler_.request_tiles(id, msg.request().count());
        break;
      case v1::WorkerMessage::kResult:
        tile_result_locked(id, msg.result());
        break;
      case v1::WorkerMessage::kReturned:
        scheduler_.return_leases(id, {msg.returned().lease_ids().begin(), msg.returned().lease_ids().end()});
        break;
      case v1::WorkerMessage::kFailed: {
        auto lease = scheduler_.lease(msg.failed().lease_id());
        if (!lease || lease->worker != id) break;  // revoked meanwhile: nothing to count
        scheduler_.fault(id, lease->tile.job, lease->id,
                         fmt::format("frame {} tile {}: worker cannot render: {}", lease->tile.frame, lease->tile.tile,
                                     msg.failed().reason()));
        break;
      }
      default:
        break;
    }
    dispatch_locked();
  });
}

void Coordinator::tile_result_locked(WorkerId id, const v1::TileResult& r) {
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
      spdlog::warn("worker {}: refused a result for unknown job '{}': {}", id, r.tile().job_id(), why);
    }
    return;
  }
  const auto rect = scheduler_.tile_rect(lease->tile.job, lease->tile.frame, lease->tile.tile);
  const std::string err = tile_error(r.tile(), *rect);
  if (!err.empty()) {
    scheduler_.fault(id, lease->tile.job, lease->id,
                     fmt::format("frame {} tile {}: {}", lease->tile.frame, lease->tile.tile, err));
    return;
  }
  // The coordinator is the authority on what the tile is: overwrite the identifying fields.
  v1::TileData tile = r.tile();
  tile.set_job_id(lease->tile.job);
  tile.set_frame(lease->tile.frame);
  tile.set_tile_index(lease->tile.tile);
  if (auto w = scheduler_.worker(id)) tile.set_worker(w->info.name);
  TileOutput out;
  out.rays = tile.rays().camera() + tile.rays().shadow() + tile.rays().secondary();
  out.seconds = tile.seconds();
  out.payload = std::make_shared<const std::string>(tile.SerializeAsString());
  const auto outcome = scheduler_.complete(id, r.lease_id(), std::move(out));
  // One line per result received: tests count re-rendered tiles from these.
  spdlog::debug("result: lease {} job {} frame {} tile {} from worker {}: {}", r.lease_id(), lease->tile.job,
                lease->tile.frame, lease->tile.tile, id,
                outcome == Scheduler::ResultOutcome::kAccepted ? "accepted" : "duplicate");
}

void Coordinator::dispatch_locked() {
  for (const Assignment& a : scheduler_.dispatch()) {
    auto it = workers_.find(a.lease.worker);
    if (it == workers_.end()) continue;
    it->second->push(assignment_message(a));
    touched_workers_.push_back(it->second);
  }
}

void Coordinator::list_workers(v1::ListWorkersResponse* out) {
  locked([&] {
    for (const auto& w : scheduler_.workers()) worker_proto(w, out->add_workers());
  });
}

}  // namespace tessera::server

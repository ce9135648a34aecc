// SPDX-License-Identifier: Apache-2.0
#include "connection.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>
#include <random>
#include <thread>

#include "farm/bundle_fetch.h"
#include "farm/channel.h"
#include "farm/span_lease.h"
#include "farm/tile_codec.h"
#include "lease_book.h"
#include "reconnect_policy.h"
#include "result_batcher.h"
#include "render/embree_device.h"
#include "render/frame_target.h"
#include "render/tile_renderer.h"

namespace tessera::worker {

namespace v1 = tessera::v1;

// One stream to the coordinator. Writes come from the reader thread, the heartbeat thread and
// the render threads, so they are serialized by `write_mu`; once `alive` is false nothing more
// is written (results for a dead session are useless: the coordinator requeued those tiles).
struct WorkerConnection::Session {
  grpc::ClientContext ctx;
  std::unique_ptr<grpc::ClientReaderWriter<v1::WorkerMessage, v1::CoordinatorMessage>> stream;
  std::mutex write_mu;
  bool alive = true;
  bool draining = false;                // stop requested: take no new work
  LeaseBook leases;                     // tiles of each lease in flight, and which were revoked
  int depth = 0;                        // tiles to keep requested or assigned and unfinished
  double tile_seconds = 0;              // a tile's wall time on one thread (moving average)
  std::chrono::milliseconds heartbeat{1000};
  // When the last message went (under write_mu): any message is a sign of life to the
  // coordinator, so a heartbeat is sent only after an interval without one. A worker busy
  // sending results sends none; a thousand of them cost the coordinator no thousand messages a
  // second for nothing.
  std::chrono::steady_clock::time_point last_write = std::chrono::steady_clock::now();
  bool result_requests = false;         // the coordinator reads TileResult.request_more
  // Set (under write_mu) at the welcome when the coordinator reads result batches. Declared last:
  // destroyed first, while the stream it writes to is still there.
  std::unique_ptr<ResultBatcher> batcher;

  bool write(const v1::WorkerMessage& m) {
    std::lock_guard lock(write_mu);
    if (!alive) return false;
    if (!stream->Write(m)) alive = false;
    last_write = std::chrono::steady_clock::now();
    return alive;
  }
  // A heartbeat, unless another message went within the interval.
  void heartbeat_if_quiet() {
    {
      std::lock_guard lock(write_mu);
      if (std::chrono::steady_clock::now() - last_write < heartbeat) return;
    }
    v1::WorkerMessage hb;
    hb.mutable_heartbeat();
    write(hb);
  }
};

WorkerConnection::WorkerConnection(WorkerOptions options)
    : options_(std::move(options)),
      cache_(options_.cache_dir, [this](const std::string& sha) { return fetch_bundle(sha); }),
      pool_(options_.threads) {
  channel_ = farm::make_coordinator_channel(options_.coordinator, options_.security);
  stub_ = v1::WorkerService::NewStub(channel_);
}

WorkerConnection::~WorkerConnection() = default;

std::string WorkerConnection::fetch_bundle(const std::string& sha256) { return farm::fetch_bundle(*stub_, sha256); }

void WorkerConnection::request_stop() {
  stop_ = true;
  std::shared_ptr<Session> s;
  {
    std::lock_guard lock(mu_);
    s = current_;
  }
  cv_.notify_all();
  if (!s) return;
  // Give back what has not started, let the running tiles finish (their results are sent by
  // the render threads), then close our side: the coordinator ends the stream. Withdrawn under
  // the write lock, with the draining flag set: no assignment is posted after it, and no render
  // thread settles a lease in the book between the withdrawal and its account. A span with tiles
  // running or sent goes back tile by tile (LeaseBook::give_back).
  v1::WorkerMessage m;
  size_t unstarted = 0;
  {
    std::lock_guard lock(s->write_mu);
    s->draining = true;
    const std::vector<TaskKey> keys = pool_.remove_all();
    unstarted = keys.size();
    if (unstarted > 0) *m.mutable_returned() = s->leases.give_back(keys);
  }
  if (unstarted > 0) {
    s->write(m);
    spdlog::info("returned {} unstarted tiles", unstarted);
  }
  pool_.wait_idle();
  ResultBatcher* batcher;
  {
    std::lock_guard lock(s->write_mu);
    batcher = s->batcher.get();
  }
  if (batcher) {
    batcher->flush();  // the last results go now, not after a linger
    const auto c = batcher->counts();
    spdlog::info("sent {} results in {} messages", c.results, c.messages);
  }
  std::lock_guard lock(s->write_mu);
  if (s->alive) s->stream->WritesDone();
  s->alive = false;
}

void WorkerConnection::sleep_backoff(std::chrono::milliseconds d) {
  std::unique_lock lock(mu_);
  cv_.wait_for(lock, d, [this] { return stop_.load(); });
}

void WorkerConnection::watch_idle() {
  using Clock = std::chrono::steady_clock;
  auto idle_since = Clock::now();
  std::unique_lock lock(mu_);
  while (!cv_.wait_for(lock, std::chrono::milliseconds(100), [this] { return stop_.load(); })) {
    // Assignments go into the pool as they arrive and leave it when their result is handed on,
    // so an empty pool is a worker without a tile (the last batch goes at once when it empties).
    if (pool_.busy() > 0) {
      idle_since = Clock::now();
    } else if (Clock::now() - idle_since >= options_.exit_when_idle) {
      lock.unlock();
      spdlog::info("no tile for {:.1f} s (--exit-when-idle): leaving",
                   std::chrono::duration<double>(options_.exit_when_idle).count());
      request_stop();
      return;
    }
  }
}

int WorkerConnection::run() {
  static thread_local std::mt19937 rng{std::random_device{}()};
  std::thread idle;
  if (options_.exit_when_idle.count() > 0) idle = std::thread([this] { watch_idle(); });
  ReconnectPolicy policy(options_.backoff_initial, options_.backoff_max);
  std::uniform_real_distribution<double> jitter(ReconnectPolicy::kMinJitter, ReconnectPolicy::kMaxJitter);
  while (!stop_) {
    const bool accepted = run_session();
    if (stop_) break;
    const auto wait = policy.next_wait(accepted, jitter(rng));
    spdlog::info("reconnecting to {} in {:.1f} s", options_.coordinator, wait.count() / 1000.0);
    if (ReconnectPolicy::how_to_wait(channel_->GetState(false) == GRPC_CHANNEL_READY) ==
        ReconnectPolicy::Wait::kFullBackoff) {
      sleep_backoff(wait);
    } else {
      farm::wait_for_coordinator(*channel_, wait, [this] { return stop_.load(); });
    }
  }
  {
    std::lock_guard lock(mu_);
    stop_ = true;  // ends watch_idle when a signal stopped us
  }
  cv_.notify_all();
  if (idle.joinable()) idle.join();
  spdlog::info("worker stopped");
  return 0;
}

bool WorkerConnection::run_session() {
  auto s = std::make_shared<Session>();
  s->stream = stub_->Connect(&s->ctx);
  {
    std::lock_guard lock(mu_);
    current_ = s;
  }
  v1::WorkerMessage reg;
  reg.mutable_register_()->set_name(options_.name);
  reg.mutable_register_()->set_threads(pool_.threads());
  reg.mutable_register_()->set_embree_isa(embree_isa());
  reg.mutable_register_()->set_version("tessera-worker 0.1.0");
  reg.mutable_register_()->set_reads_assignment_batches(true);
  reg.mutable_register_()->set_reads_spans(true);
  bool accepted = false;
  std::thread heartbeat;
  std::mutex hb_mu;
  std::condition_variable hb_cv;
  bool hb_stop = false;

  if (s->write(reg)) {
    v1::CoordinatorMessage msg;
    while (s->stream->Read(&msg)) {
      switch (msg.msg_case()) {
        case v1::CoordinatorMessage::kWelcome: {
          accepted = true;
          s->heartbeat = std::chrono::milliseconds(std::max(50, msg.welcome().heartbeat_interval_ms()));
          s->result_requests = msg.welcome().reads_request_more();
          if (msg.welcome().reads_result_batches()) {
            auto batcher = std::make_unique<ResultBatcher>(
                options_.batching, options_.batching.bytes_limit(msg.welcome().max_message_bytes()),
                [raw = s.get()](const v1::WorkerMessage& m) { return raw->write(m); });
            std::lock_guard lock(s->write_mu);
            s->batcher = std::move(batcher);
          }
          spdlog::info("connected to {} as worker {} ({} threads, Embree {})", options_.coordinator,
                       msg.welcome().worker_id(), pool_.threads(), embree_isa());
          heartbeat = std::thread([&, s] {
            std::unique_lock lock(hb_mu);
            // Woken twice an interval, so a quiet stream is never silent for much more than one.
            while (!hb_cv.wait_for(lock, s->heartbeat / 2, [&] { return hb_stop; })) s->heartbeat_if_quiet();
          });
          // Pull: keep twice as many tiles as threads on hand so no thread waits for the network;
          // once tile times are known, more to cover the time results wait for a batch.
          v1::WorkerMessage req;
          {
            std::lock_guard lock(s->write_mu);
            s->depth = 2 * pool_.threads();
            req.mutable_request()->set_count(s->depth);
          }
          if (!stop_) s->write(req);
          break;
        }
        case v1::CoordinatorMessage::kAssignment:
          handle_assignment(s, msg.assignment());
          break;
        case v1::CoordinatorMessage::kAssignments:
          for (const v1::Assignment& a : msg.assignments().assignments()) handle_assignment(s, a);
          break;
        case v1::CoordinatorMessage::kRevoke: {
          // Unstarted tiles leave the pool now; running ones' results are dropped as they finish.
          // The pool and the book change under one lock, so no tile finishes in between.
          size_t freed = 0;
          v1::WorkerMessage req;
          {
            std::lock_guard lock(s->write_mu);
            for (uint64_t id : msg.revoke().lease_ids()) {
              const size_t n = pool_.remove(id);
              freed += n;
              s->leases.withdrawn(id, n);
              s->leases.revoke(id);
            }
            for (const v1::LeaseTile& t : msg.revoke().tiles()) {
              if (pool_.remove(t.lease_id(), t.tile_index())) {
                ++freed;
                s->leases.withdrawn(t.lease_id(), 1);
              } else {
                s->leases.revoke(t.lease_id(), t.tile_index());
              }
            }
            if (freed == 0 || s->draining) break;
            // Tiles, not leases: the pull counts tiles, and a span's took as many as it has.
            req.mutable_request()->set_count(int(freed));
          }
          s->write(req);
          break;
        }
        default:
          break;
      }
    }
  }
  {
    std::lock_guard lock(s->write_mu);
    s->alive = false;
  }
  {
    std::lock_guard lock(hb_mu);
    hb_stop = true;
  }
  hb_cv.notify_all();
  if (heartbeat.joinable()) heartbeat.join();
  // Tiles of a dead session are requeued by the coordinator: do not render them.
  if (!stop_) pool_.remove_all();
  grpc::Status status = s->stream->Finish();
  {
    std::lock_guard lock(mu_);
    current_.reset();
  }
  if (stop_) {
    spdlog::info("left the coordinator");
  } else if (status.error_code() == grpc::StatusCode::UNAVAILABLE && !accepted) {
    spdlog::warn("coordinator at {} unreachable: {}", options_.coordinator, status.error_message());
  } else {
    spdlog::warn("session with {} ended: {} ({})", options_.coordinator, status.error_message(),
                 int(status.error_code()));
  }
  return accepted;
}

void WorkerConnection::handle_assignment(const std::shared_ptr<Session>& s, const v1::Assignment& a) {
  // A span lease becomes one task per tile, each rendered and reported as a single-tile lease.
  std::vector<v1::Assignment> tiles;
  const std::string problem = farm::split_span(a, &tiles);
  const bool hold = options_.test_fault == "idle";  // holds the lease, heartbeats, never renders
  bool draining;
  {
    // Checked and posted under the lock request_stop withdraws under: nothing is posted after
    // the worker gave back its unstarted tiles.
    std::lock_guard lock(s->write_mu);
    draining = s->draining;
    if (!draining && !hold && problem.empty()) {
      s->leases.posted(a.lease_id(), tiles.front().tile_index(), int(tiles.size()));
      const bool span = farm::is_span(a);
      for (v1::Assignment& t : tiles) {
        const TaskKey key{t.lease_id(), t.tile_index()};
        pool_.post(key, [this, s, t = std::move(t), span] { render(s, t, span); });
      }
    }
  }
  if (draining) {  // arrived after we returned our tiles: give it back too (whole: none of it started)
    v1::WorkerMessage m;
    m.mutable_returned()->add_lease_ids(a.lease_id());
    s->write(m);
    return;
  }
  if (!hold && !problem.empty()) refuse_span(s, a, problem);
}

void WorkerConnection::refuse_span(const std::shared_ptr<Session>& s, const v1::Assignment& a,
                                   const std::string& problem) {
  // Answered as a render failure: the coordinator requeues the lease's tiles and counts a fault,
  // so a coordinator that keeps sending such spans ends up sending this worker none of the job.
  spdlog::error("job {} frame {}: malformed span lease {}: {}", a.job_id(), a.frame(), a.lease_id(), problem);
  v1::WorkerMessage out;
  out.mutable_failed()->set_lease_id(a.lease_id());
  out.mutable_failed()->set_reason("malformed span lease: " + problem);
  int ask = 0;
  {
    // Replace the tiles the lease took of our requests, as a failed tile is replaced; a tile
    // count that is itself the problem can have taken no more than all of them.
    std::lock_guard lock(s->write_mu);
    if (!s->draining) ask = std::clamp(a.tile_count(), 1, std::max(1, s->depth));
  }
  s->write(out);
  if (ask > 0) {
    v1::WorkerMessage req;
    req.mutable_request()->set_count(ask);
    s->write(req);
  }
}

void WorkerConnection::inject_test_fault(v1::TileResult* r) const {
  const std::string& f = options_.test_fault;
  if (f.empty()) return;
  if (f == "nan") {
    std::string rgb = r->tile().rgb();
    const uint32_t nan_bits = 0x7fc00000u;  // little-endian float32 quiet NaN
    for (int i = 0; i < 4 && size_t(i) < rgb.size(); ++i) rgb[size_t(i)] = char((nan_bits >> (8 * i)) & 0xff);
    r->mutable_tile()->set_rgb(rgb);
  } else if (f == "wrong-size") {
    std::string rgb = r->tile().rgb();
    rgb.resize(rgb.size() >= 12 ? rgb.size() - 12 : 0);
    r->mutable_tile()->set_rgb(rgb);
  } else if (f == "no-block-stats") {
    r->mutable_tile()->clear_block_stats();
  } else if (f == "stale") {
    r->set_lease_id(r->lease_id() + (uint64_t(1) << 40));
  } else if (f == "no-scene" || f == "long-reason") {
    throw std::runtime_error("cannot load the scene (--test-fault=no-scene)");
  } else if (f == "negative-variance") {
    std::string v = r->tile().variance_bf16();
    if (v.size() >= 2) {
      v[0] = char(0x80);  // bfloat16 -1.0 (0xbf80), little-endian
      v[1] = char(0xbf);
    }
    r->mutable_tile()->set_variance_bf16(v);
  } else if (f == "nan-seconds") {
    r->mutable_tile()->set_seconds(std::numeric_limits<double>::quiet_NaN());
  } else if (f == "absurd-seconds") {  // finite, but longer than any lease has existed
    r->mutable_tile()->set_seconds(1e300);
  } else if (f == "absurd-spp") {
    r->mutable_tile()->clear_spp();
    r->mutable_tile()->set_uniform_spp(std::numeric_limits<uint32_t>::max());
  } else if (f == "other-job") {  // an honest tile, claimed for a job that is not its lease's
    r->mutable_tile()->set_job_id("0123456789ab");
  } else if (f == "padded") {  // honest pixels, plus fields no version of the protocol defines
    const auto unknown = [](google::protobuf::Message* m) { return m->GetReflection()->MutableUnknownFields(m); };
    unknown(r->mutable_tile())->AddLengthDelimited(999, std::string(size_t(1) << 20, 'x'));
    unknown(r->mutable_tile()->mutable_rays())->AddLengthDelimited(998, std::string(4096, 'y'));
  }
}

void WorkerConnection::render(const std::shared_ptr<Session>& s, const v1::Assignment& a, bool span) {
  const auto started = std::chrono::steady_clock::now();
  v1::WorkerMessage out;
  try {
    // --test-fault other-frame: the next frame's pixels, claimed as the next frame's.
    const int frame = a.frame() + (options_.test_fault == "other-frame" ? 1 : 0);
    auto scene = cache_.frame(a.bundle_sha256(), a.overrides().SerializeAsString(), frame);
    const TileRect rect = farm::from_proto(a.rect());
    TileResult tile;
    if (image_settings(*scene).frame_target()) {
      // A pass of a frame target: the tile's blocks to the counts the coordinator planned from the
      // frame's last pass (sampling/pass_plan.h); the result carries their statistics.
      SamplePlan plan;
      if (std::string problem = decode_plan(a.sample_plan(), &plan); !problem.empty()) {
        throw std::runtime_error(problem);
      }
      tile = render_tile_planned(*scene, rect, plan);
    } else {
      tile = render_tile(*scene, rect);
    }
    auto* r = out.mutable_result();
    r->set_lease_id(a.lease_id());
    r->mutable_tile()->set_job_id(a.job_id());
    r->mutable_tile()->set_frame(frame);
    r->mutable_tile()->set_tile_index(a.tile_index());
    r->mutable_tile()->set_worker(options_.name);
    farm::encode_tile(tile, r->mutable_tile());
    if (options_.extra_delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(options_.extra_delay_ms));
    inject_test_fault(r);
  } catch (const std::exception& e) {
    // The coordinator validated the scene; failing here means this machine cannot render it
    // (bundle download failed, mesh unreadable...). Say so: the coordinator requeues the tile for
    // someone else and, after a few such faults, stops sending us this job.
    spdlog::error("job {} frame {} tile {}: cannot render: {}", a.job_id(), a.frame(), a.tile_index(), e.what());
    out.Clear();
    out.mutable_failed()->set_lease_id(a.lease_id());
    out.mutable_failed()->set_reason(options_.test_fault == "long-reason" ? std::string(20 << 20, 'r') : e.what());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  int ask = 0;
  size_t withdrawn = 0;
  ResultBatcher* batcher;
  {
    std::lock_guard lock(s->write_mu);
    if (s->leases.finished(a.lease_id(), a.tile_index())) {
      out.Clear();  // another copy won, or the job was cancelled
    } else if (span && out.has_failed()) {
      // The failure ends the whole lease at the coordinator: the span's other tiles are not
      // rendered (the unstarted are withdrawn, and replaced below), and results of the running
      // ones are dropped as a revoked lease's are (one failure reported, not one a tile).
      withdrawn = pool_.remove(a.lease_id());
      s->leases.withdrawn(a.lease_id(), withdrawn);
      s->leases.revoke(a.lease_id());
    }
    batcher = s->batcher.get();
    if (!s->draining) {
      // Replace this tile, and move the depth toward what covers the linger at the tile times
      // measured so far (one step down at a time, all the way up at once).
      s->tile_seconds = s->tile_seconds > 0 ? 0.8 * s->tile_seconds + 0.2 * seconds : seconds;
      const int want = batcher ? options_.batching.depth(pool_.threads(), s->tile_seconds) : 2 * pool_.threads();
      ask = 1;
      if (want > s->depth) {
        ask += want - s->depth;
        s->depth = want;
      } else if (want < s->depth) {
        ask = 0;
        --s->depth;
      }
      ask += int(withdrawn);
    }
  }
  if (out.has_result() && batcher) {
    batcher->add(std::move(*out.mutable_result()), ask, pool_.queued() == 0);
    return;
  }
  // The next tile's request rides on the result where the coordinator reads it there.
  if (out.has_result() && ask > 0 && s->result_requests) {
    out.mutable_result()->set_request_more(ask);
    ask = 0;
  }
  // The span's results still waiting for company go before the failure that ends its lease.
  if (out.has_failed() && span && batcher) batcher->flush();
  if (out.msg_case() != v1::WorkerMessage::MSG_NOT_SET) s->write(out);
  if (ask > 0) {
    v1::WorkerMessage req;
    req.mutable_request()->set_count(ask);
    s->write(req);
  }
}

}  // namespace tessera::worker

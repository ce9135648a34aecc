// SPDX-License-Identifier: Apache-2.0
#include "sim_worker.h"

#include "farm/span_lease.h"
#include "farm/tile_codec.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <utility>

namespace tessera::bench {

namespace v1 = tessera::v1;

// ------------------------------------------------------------------------------------------
// SimTimer

SimTimer::SimTimer() : thread_([this] { loop(); }) {}

SimTimer::~SimTimer() { stop(); }

void SimTimer::at(SteadyClock::time_point when, std::function<void()> f) {
  {
    std::lock_guard lock(mu_);
    if (stop_) return;
    q_.push(Entry{when, seq_++, std::move(f)});
  }
  cv_.notify_one();
}

void SimTimer::stop() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
    while (!q_.empty()) q_.pop();
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void SimTimer::loop() {
  std::unique_lock lock(mu_);
  while (!stop_) {
    if (q_.empty()) {
      cv_.wait(lock);
      continue;
    }
    const auto when = q_.top().when;
    if (SteadyClock::now() < when) {
      cv_.wait_until(lock, when);
      continue;
    }
    auto f = std::move(const_cast<Entry&>(q_.top()).f);
    q_.pop();
    lock.unlock();
    f();
    lock.lock();
  }
}

// ------------------------------------------------------------------------------------------
// SimWorker


SimWorker::SimWorker(v1::WorkerService::Stub* stub, std::string name, SimOptions options, SimTimer& timer,
                     SimCounters& counters)
    : stub_(stub), name_(std::move(name)), options_(options), timer_(timer), counters_(counters) {}

void SimWorker::start() {
  stub_->async()->Connect(&ctx_, this);
  v1::WorkerMessage reg;
  reg.mutable_register_()->set_name(name_);
  reg.mutable_register_()->set_threads(options_.threads);
  reg.mutable_register_()->set_embree_isa("simulated");
  reg.mutable_register_()->set_version("coordinator_load (simulated worker)");
  reg.mutable_register_()->set_reads_assignment_batches(options_.batches);
  reg.mutable_register_()->set_reads_spans(options_.spans);
  // The hold keeps OnDone away while the timer thread may still start writes (see stop()).
  AddHold();
  send(std::move(reg));
  StartRead(&in_);
  StartCall();
}

void SimWorker::go() {
  // A simulated tile's time is known in advance; a delay of 0 counts as the shortest tile there
  // is (the depth's cap), as tessera-worker's measured tile time would come out.
  const double seconds = std::max(1e-6, std::chrono::duration<double>(options_.delay).count());
  request(result_batches_ ? options_.batching.depth(options_.threads, seconds) : 2 * options_.threads);
}

void SimWorker::request(int count) {
  v1::WorkerMessage m;
  m.mutable_request()->set_count(count);
  send(std::move(m));
}

void SimWorker::heartbeat() {
  // As tessera-worker does: a heartbeat only after an interval without any other message, checked
  // twice an interval.
  bool quiet = false;
  {
    std::lock_guard lock(mu_);
    if (stopped_) return;
    quiet = SteadyClock::now() - last_send_ >= heartbeat_interval_;
  }
  if (quiet) {
    v1::WorkerMessage m;
    m.mutable_heartbeat();
    send(std::move(m));
    counters_.heartbeats++;
  }
  timer_.at(SteadyClock::now() + heartbeat_interval_ / 2, [this] { heartbeat(); });
}

void SimWorker::send(v1::WorkerMessage m) {
  std::unique_lock lock(mu_);
  if (stopped_) return;
  counters_.bytes_out += int64_t(m.ByteSizeLong());
  last_send_ = SteadyClock::now();
  queue_.push_back(std::move(m));
  if (writing_) return;
  writing_ = true;
  current_ = std::move(queue_.front());
  queue_.pop_front();
  lock.unlock();
  StartWrite(&current_);
}

// Called with mu_ held, once no more writes will start: the hold may go.
void SimWorker::release_hold_locked(bool* release) {
  *release = !writing_ && !hold_released_;
  if (*release) hold_released_ = true;
}

void SimWorker::OnWriteDone(bool ok) {
  std::unique_lock lock(mu_);
  if (!ok) stopped_ = true;  // the stream is broken
  if (stopped_ || queue_.empty()) {
    writing_ = false;
    bool release = false;
    if (stopped_) release_hold_locked(&release);
    lock.unlock();
    if (release) RemoveHold();
    return;
  }
  current_ = std::move(queue_.front());
  queue_.pop_front();
  lock.unlock();
  StartWrite(&current_);
}

void SimWorker::OnReadDone(bool ok) {
  if (!ok) {  // the coordinator ended the stream, or we cancelled it
    bool release = false;
    {
      std::lock_guard lock(mu_);
      if (!stopped_) ended_early_ = true;
      stopped_ = true;
      release_hold_locked(&release);
    }
    if (release) RemoveHold();
    return;
  }
  counters_.bytes_in += int64_t(in_.ByteSizeLong());
  switch (in_.msg_case()) {
    case v1::CoordinatorMessage::kWelcome:
      heartbeat_interval_ = std::chrono::milliseconds(std::max(50, in_.welcome().heartbeat_interval_ms()));
      result_requests_ = in_.welcome().reads_request_more();
      result_batches_ = options_.batches && in_.welcome().reads_result_batches();
      timer_.at(SteadyClock::now() + heartbeat_interval_ / 2, [this] { heartbeat(); });
      welcomed_ = true;
      break;
    case v1::CoordinatorMessage::kAssignment:
      assigned(in_.assignment(), false);
      break;
    case v1::CoordinatorMessage::kAssignments: {
      const auto& all = in_.assignments().assignments();
      for (int i = 0; i < all.size(); ++i) assigned(all[i], i + 1 < all.size());
      break;
    }
    case v1::CoordinatorMessage::kRevoke: {
      // Every tile of a revoked lease still "rendering", or the one tile named; the results are
      // dropped when the timer ends them (the tiles are not withdrawn: the sim has no queue).
      std::lock_guard lock(mu_);
      const auto revoke = [this](std::pair<uint64_t, int> key) {
        if (pending_.count(key) && revoked_.insert(key).second) counters_.revoked++;
      };
      for (uint64_t id : in_.revoke().lease_ids()) {
        for (auto it = pending_.lower_bound({id, std::numeric_limits<int>::min()});
             it != pending_.end() && it->first == id; ++it) {
          revoke(*it);
        }
      }
      for (const v1::LeaseTile& t : in_.revoke().tiles()) revoke({t.lease_id(), t.tile_index()});
      break;
    }
    default:
      break;
  }
  StartRead(&in_);
}

void SimWorker::assigned(const v1::Assignment& a, bool more_in_message) {
  counters_.assignments++;
  // A span lease's tiles (Assignment.tile_count), cut and checked as tessera-worker does.
  std::vector<v1::Assignment> tiles;
  if (const std::string problem = farm::split_span(a, &tiles); !problem.empty()) {
    counters_.refused++;
    v1::WorkerMessage m;
    m.mutable_failed()->set_lease_id(a.lease_id());
    m.mutable_failed()->set_reason("malformed span lease (simulated worker): " + problem);
    send(std::move(m));
    request(std::clamp(a.tile_count(), 1, farm::kMaxSpanTiles));
    return;
  }
  counters_.assigned_tiles += int64_t(tiles.size());
  if (options_.delay.count() == 0) {
    // The results of one message of assignments go together.
    for (size_t i = 0; i < tiles.size(); ++i) finish_tile(tiles[i], more_in_message || i + 1 < tiles.size());
    return;
  }
  {
    std::lock_guard lock(mu_);
    for (const v1::Assignment& t : tiles) pending_.emplace(t.lease_id(), t.tile_index());
  }
  // Every tile of a span "renders" at once, as every lease does here: the sim has no threads.
  const auto when = SteadyClock::now() + options_.delay;
  for (v1::Assignment& t : tiles) timer_.at(when, [this, t = std::move(t)] { finish_tile(t, false); });
}

void SimWorker::finish_tile(const v1::Assignment& a, bool more_coming) {
  bool revoked;
  {
    std::lock_guard lock(mu_);
    pending_.erase({a.lease_id(), a.tile_index()});
    revoked = revoked_.erase({a.lease_id(), a.tile_index()}) > 0;
  }
  if (revoked) {  // like tessera-worker: a revoked tile's result is discarded, the slot refilled
    request(1);
    return;
  }
  // The tile a worker would return, encoded as tessera-worker encodes it (farm/tile_codec.h).
  // The values do not matter to the coordinator (it checks only sizes, position and that they
  // are finite), so they are constant.
  TileResult tile;
  tile.rect = farm::from_proto(a.rect());
  const size_t pixels = size_t(std::max(0, tile.rect.width)) * size_t(std::max(0, tile.rect.height));
  tile.rgb.assign(3 * pixels, 0.5f);
  tile.variance.assign(pixels, 0.0f);
  tile.spp.assign(pixels, 1);
  tile.rays.camera = pixels;
  tile.seconds = std::chrono::duration<double>(options_.delay).count();
  v1::TileResult r;
  r.set_lease_id(a.lease_id());
  auto* t = r.mutable_tile();
  t->set_job_id(a.job_id());
  t->set_frame(a.frame());
  t->set_tile_index(a.tile_index());
  t->set_worker(name_);
  farm::encode_tile(tile, t);
  counters_.results++;
  if (!result_batches_) {
    // Like tessera-worker without batches: the next tile's request rides on the result when the
    // coordinator reads it there.
    v1::WorkerMessage out;
    *out.mutable_result() = std::move(r);
    const bool rides = result_requests_;
    if (rides) out.mutable_result()->set_request_more(1);
    send(std::move(out));
    counters_.result_messages++;
    if (!rides) request(1);
    return;
  }
  // Like tessera-worker's ResultBatcher: the batch goes when it is full or nothing else is
  // rendering here; otherwise when its first result has waited the linger.
  std::unique_lock lock(mu_);
  v1::TileResults* b = batch_.mutable_results();
  const bool started = b->results_size() == 0;
  *b->add_results() = std::move(r);
  b->set_request_more(b->request_more() + 1);
  const bool now = size_t(b->results_size()) >= options_.batching.max_tiles || (!more_coming && pending_.empty());
  if (now) {
    send_batch(lock);
  } else if (started) {
    const uint64_t gen = batch_gen_;
    lock.unlock();
    timer_.at(SteadyClock::now() + options_.batching.linger, [this, gen] { flush_batch(gen); });
  }
}

void SimWorker::flush_batch(uint64_t gen) {
  std::unique_lock lock(mu_);
  if (gen != batch_gen_ || batch_.results().results_size() == 0) return;
  send_batch(lock);
}

void SimWorker::send_batch(std::unique_lock<std::mutex>& lock) {
  v1::WorkerMessage out = std::move(batch_);
  batch_.Clear();
  ++batch_gen_;
  lock.unlock();
  send(std::move(out));
  counters_.result_messages++;
}

void SimWorker::stop() {
  bool release = false;
  {
    std::lock_guard lock(mu_);
    if (!stopped_) {
      stopped_ = true;
      queue_.clear();
    }
    release_hold_locked(&release);
  }
  ctx_.TryCancel();
  if (release) RemoveHold();
}

void SimWorker::OnDone(const grpc::Status& s) {
  std::lock_guard lock(done_mu_);
  status_ = s;
  done_ = true;
  done_cv_.notify_all();
}

bool SimWorker::wait_done(SteadyClock::time_point deadline) {
  std::unique_lock lock(done_mu_);
  return done_cv_.wait_until(lock, deadline, [this] { return done_; });
}

}  // namespace tessera::bench

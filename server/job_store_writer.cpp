// SPDX-License-Identifier: Apache-2.0
// The group-commit writer: one thread takes everything queued in a commit window as a batch and
// applies it in three steps (the segment, the rows, the deletions), retrying a failed batch every
// second; on a full disk it lets through what needs no new segment and makes room (job_store.h).
#include <spdlog/spdlog.h>

#include <chrono>
#include <set>
#include <unordered_set>

#include "job_row.h"
#include "job_store.h"
#include "sqlite_util.h"

namespace tessera::server {

void JobStore::writer_loop() {
  std::vector<Op> pending;
  while (true) {
    {
      std::unique_lock lock(mu_);
      const auto shed_waiting = [&] { return !to_shed_.empty() && !shed_failing_; };
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty() || !pending.empty() || shed_waiting(); });
      if (pending.empty() && queue_.empty()) {
        if (stopping_) break;  // rows not yet shed are shed after the next start
        lock.unlock();
        shed_chunk();  // nothing to write: shed the rows of evicted jobs meanwhile
        continue;
      }
      // The commit window (job_store.h): let the tiles finishing meanwhile join this batch.
      if (pending.empty() && commit_window_.count() > 0) {
        cv_.wait_for(lock, commit_window_,
                     [&] { return stopping_ || barrier_queued_ || queue_.size() >= kMaxBatchOps; });
      }
      barrier_queued_ = false;
      // Everything queued so far is one batch: under load batches grow and commits stay few.
      for (auto& op : queue_) pending.push_back(std::move(op));
      queue_.clear();
    }
    std::vector<Op> deferred;
    const std::string error = apply_pending(pending, deferred);
    std::vector<std::shared_ptr<std::promise<std::string>>> barriers;
    for (auto it = pending.begin(); it != pending.end();) {
      if (auto* b = std::get_if<Barrier>(&*it)) {
        barriers.push_back(b->done);
        it = pending.erase(it);
      } else {
        ++it;
      }
    }
    // Answered after the bookkeeping below: whoever waited on a barrier sees its batch counted.
    auto answer_barriers = [&] {
      for (auto& done : barriers) done->set_value(error);
    };
    if (error.empty() && reserve_.wanted()) reserve_.make();  // writer thread: no lock needed
    if (error.empty()) {
      {
        std::lock_guard lock(mu_);
        if (!healthy_) {
          spdlog::info("storage recovered: {} writes committed", pending.size());
          reserve_.want();
        }
        healthy_ = true;
        shed_failing_ = false;
        ++stats_.batches;
        stats_.ops += int64_t(pending.size());
      }
      pending.clear();
      answer_barriers();
      shed_chunk();  // one chunk after each batch: the rows go under load too, a little at a time
      continue;
    }
    answer_barriers();
    if (!deferred.empty()) {
      // Everything else was committed: only the deferred tiles are left (barriers were answered
      // with the error above: the tiles before them are not durable yet).
      std::lock_guard lock(mu_);
      stats_.ops += int64_t(pending.size() - deferred.size());
      pending = std::move(deferred);
    }
    bool stopping;
    {
      std::lock_guard lock(mu_);
      healthy_ = false;
      last_error_ = error;
      ++stats_.failures;
      stopping = stopping_;
    }
    spdlog::error("cannot persist {} writes, new jobs are refused until this is fixed (retrying every second): {}",
                  pending.size(), error);
    if (stopping) {
      spdlog::error("stopping with {} writes not persisted: their tiles will be rendered again", pending.size());
      break;
    }
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, std::chrono::seconds(1), [&] { return stopping_; });
  }
}

std::string JobStore::apply_pending(std::vector<Op>& pending, std::vector<Op>& deferred) {
  std::string error;
  try {
    const auto start = std::chrono::steady_clock::now();
    apply(pending);
    report_batch(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), pending);
  } catch (const std::exception& e) {
    error = e.what();
    // A full disk: whatever needs no new segment goes through now, above all the
    // acknowledgements, whose commit deletes segments and so makes the room the rest needs.
    // The tiles still to write stay queued, in order, ahead of anything queued later.
    try {
      deferred = apply(pending, false);
      if (deferred.empty()) {
        error.clear();  // nothing needed a segment: the retry simply went through
      } else {
        spdlog::warn("storage: committed {} writes that need no new tile segment; {} finished tiles wait for "
                     "space", pending.size() - deferred.size(), deferred.size());
      }
    } catch (const std::exception& e2) {
      deferred.clear();
      spdlog::debug("storage: even the writes that need no new segment failed: {}", e2.what());
      // SQLite itself has no room left. Make room with what the client already has, and
      // with the reserve, so that SQLite can checkpoint and cut its WAL back.
      reclaim_delivered(pending);
      release_reserve();
    }
  }
  return error;
}

void JobStore::report_batch(double seconds, const std::vector<Op>& batch) {
  std::lock_guard lock(observer_mu_);
  if (!batch_observer_) return;
  uint64_t bytes = 0;
  for (const Op& op : batch) {
    if (const auto* t = std::get_if<TileDone>(&op); t && t->payload) bytes += t->payload->size();
  }
  batch_observer_(seconds, bytes);
}

// What apply() works out about a batch before it writes anything.
struct JobStore::BatchPlan {
  // Tiles of frames acknowledged (or jobs evicted) in this same batch need no pixels on disk:
  // the client has them. Their rows are written with no location (segment 0), and only the
  // rows: this is what lets acknowledgements through when the disk is full.
  std::set<FrameKey> delivered;
  std::set<JobId> evicted;
  bool needs_pixels(const TileDone& t) const {
    return !delivered.count({t.key.job, t.key.frame}) && !evicted.count(t.key.job);
  }
  std::vector<bool> skip;  // ops left out of this batch (tiles needing a segment, without one)
  // A lease issued and ended within one batch never needs a row.
  std::unordered_set<LeaseId> transient;
  LeaseId hwm = 0;  // the lease high-water mark once the batch is committed
  std::vector<TileStore::Location> at;  // where the tiles that need pixels went, in batch order
};

std::vector<JobStore::Op> JobStore::apply(std::vector<Op>& batch, bool new_segment) {
  BatchPlan plan = plan_batch(batch, new_segment);
  // 1. One segment with every tile of the batch that needs one, durable before any row that
  // says "done".
  write_pixels(batch, plan);
  // 2. One transaction, in queue order.
  commit_rows(batch, plan);
  lease_hwm_ = plan.hwm;
  // 3. Only now may pixels go: the rows that say the client has them are committed.
  return release_delivered(batch, plan);
}

JobStore::BatchPlan JobStore::plan_batch(const std::vector<Op>& batch, bool new_segment) const {
  BatchPlan plan;
  for (const Op& op : batch) {
    if (const auto* a = std::get_if<FrameAck>(&op)) plan.delivered.insert({a->job, a->frame});
    if (const auto* v = std::get_if<Evicted>(&op)) plan.evicted.insert(v->job);
  }
  plan.skip.assign(batch.size(), false);
  if (!new_segment) {
    for (size_t i = 0; i < batch.size(); ++i) {
      const auto* t = std::get_if<TileDone>(&batch[i]);
      if (t && plan.needs_pixels(*t)) plan.skip[i] = true;
    }
  }
  std::unordered_set<LeaseId> issued;
  plan.hwm = lease_hwm_;
  for (const Op& op : batch) {
    if (const auto* l = std::get_if<LeaseIssued>(&op)) {
      issued.insert(l->id);
      plan.hwm = std::max(plan.hwm, l->id);
    } else if (const auto* e = std::get_if<LeaseEnded>(&op)) {
      if (issued.count(e->id)) plan.transient.insert(e->id);
    }
  }
  return plan;
}

void JobStore::write_pixels(const std::vector<Op>& batch, BatchPlan& plan) {
  std::vector<const std::string*> payloads;
  for (size_t i = 0; i < batch.size(); ++i) {
    const auto* t = std::get_if<TileDone>(&batch[i]);
    if (t && !plan.skip[i] && plan.needs_pixels(*t)) payloads.push_back(t->payload.get());
  }
  if (!payloads.empty()) plan.at = tiles_->append(payloads);
}

void JobStore::commit_rows(const std::vector<Op>& batch, const BatchPlan& plan) {
  exec("BEGIN IMMEDIATE");
  try {
    size_t next_at = 0;
    for (size_t i = 0; i < batch.size(); ++i) {
      if (!plan.skip[i]) write_row(batch[i], plan, next_at);
    }
    if (plan.hwm != lease_hwm_) {
      sqlite3_bind_int64(set_hwm_, 1, int64_t(plan.hwm));
      step(set_hwm_);
    }
    exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    // No row points at this batch's records: they are taken back, and the retry appends them
    // again. (Were this lost in a crash, they would be dead bytes, or an orphan segment deleted
    // at the next start.)
    if (!plan.at.empty()) tiles_->undo_last_append();
    throw;
  }
}

void JobStore::write_row(const Op& op, const BatchPlan& plan, size_t& next_at) {
  if (const auto* j = std::get_if<JobRow>(&op)) {
    sqlite3_stmt* st = j->insert ? ins_job_ : upd_job_;
    if (j->insert) {
      bind_job_insert(st, j->s);
    } else {
      bind_job_update(st, j->s);
    }
    step(st);
  } else if (const auto* t = std::get_if<TileDone>(&op)) {
    bind_text(ins_tile_, 1, t->key.job);
    sqlite3_bind_int(ins_tile_, 2, t->key.frame);
    sqlite3_bind_int(ins_tile_, 3, t->key.tile);
    sqlite3_bind_int64(ins_tile_, 4, int64_t(t->rays));
    sqlite3_bind_double(ins_tile_, 5, t->seconds);
    const TileStore::Location nowhere{};  // segment 0: never a file (numbers start at 1)
    const TileStore::Location& loc = plan.needs_pixels(*t) ? plan.at[next_at++] : nowhere;
    sqlite3_bind_int64(ins_tile_, 6, loc.segment);
    sqlite3_bind_int64(ins_tile_, 7, loc.offset);
    sqlite3_bind_int64(ins_tile_, 8, loc.length);
    step(ins_tile_);
  } else if (const auto* a = std::get_if<FrameAck>(&op)) {
    bind_text(ins_ack_, 1, a->job);
    sqlite3_bind_int(ins_ack_, 2, a->frame);
    step(ins_ack_);
  } else if (const auto* l = std::get_if<LeaseIssued>(&op)) {
    if (plan.transient.count(l->id)) return;
    sqlite3_bind_int64(ins_lease_, 1, int64_t(l->id));
    bind_text(ins_lease_, 2, l->worker);
    bind_text(ins_lease_, 3, l->tile.job);
    sqlite3_bind_int(ins_lease_, 4, l->tile.frame);
    sqlite3_bind_int(ins_lease_, 5, l->tile.tile);
    sqlite3_bind_double(ins_lease_, 6, l->issued);
    step(ins_lease_);
  } else if (const auto* e = std::get_if<LeaseEnded>(&op)) {
    if (plan.transient.count(e->id)) return;
    sqlite3_bind_int64(del_lease_, 1, int64_t(e->id));
    step(del_lease_);
  } else if (const auto* v = std::get_if<Evicted>(&op)) {
    bind_text(evict_, 1, v->job);
    step(evict_);
  } else if (const auto* b = std::get_if<Blocklisted>(&op)) {
    bind_text(ins_block_, 1, b->job);
    bind_text(ins_block_, 2, b->worker);
    step(ins_block_);
  }
}

void JobStore::step(sqlite3_stmt* st) {
  const int rc = sqlite3_step(st);
  sqlite3_reset(st);
  sqlite3_clear_bindings(st);
  if (rc != SQLITE_DONE) throw std::runtime_error(db_path_.string() + ": " + sqlite3_errmsg(db_));
}

std::vector<JobStore::Op> JobStore::release_delivered(const std::vector<Op>& batch, const BatchPlan& plan) {
  // Bookkeeping in queue order; a segment is deleted once no tile of an unacknowledged frame is
  // left in it.
  std::vector<Op> deferred;
  std::vector<int64_t> emptied;
  size_t next_at = 0;
  for (size_t i = 0; i < batch.size(); ++i) {
    const Op& op = batch[i];
    if (plan.skip[i]) {
      deferred.push_back(op);
    } else if (const auto* t = std::get_if<TileDone>(&op)) {
      if (plan.needs_pixels(*t)) segments_.track(t->key, plan.at[next_at++].segment);
    } else if (const auto* a = std::get_if<FrameAck>(&op)) {
      segments_.release_frame({a->job, a->frame}, emptied);
    } else if (const auto* v = std::get_if<Evicted>(&op)) {
      segments_.release_job(v->job, emptied);
      queue_shedding(v->job);  // its rows are shed now that its eviction is committed
    }
  }
  // A segment can empty and then gain a later tile of the same batch: checked at the end.
  for (int64_t seg : emptied) {
    if (segments_.forget_if_empty(seg)) tiles_->remove_segment(seg);
  }
  return deferred;
}

void JobStore::reclaim_delivered(const std::vector<Op>& pending) {
  // The segments that the queued acknowledgements (and evictions) will delete once committed,
  // deleted now, because on a full disk the commit cannot happen until something is deleted.
  // The bookkeeping is left alone: it is updated when the commit goes through (deleting again
  // is harmless). The price: should the coordinator die before that commit, those frames are
  // not acknowledged in the database and their rows point nowhere, so they are rendered again
  // (never served wrong); without this, a full disk never recovers while running.
  std::vector<FrameKey> frames;
  for (const Op& op : pending) {
    if (const auto* a = std::get_if<FrameAck>(&op)) {
      frames.push_back({a->job, a->frame});
    } else if (const auto* v = std::get_if<Evicted>(&op)) {
      for (const FrameKey& f : segments_.frames_of(v->job)) frames.push_back(f);
    }
  }
  const std::vector<int64_t> emptied = segments_.would_empty(frames);
  if (emptied.empty()) return;
  for (int64_t seg : emptied) tiles_->remove_segment(seg);
  spdlog::warn("disk full: deleted {} tile segments holding only frames a client already has (their "
               "acknowledgements are not committed yet) to make room",
               emptied.size());
}

void JobStore::release_reserve() {
  reserve_.release();
  // Copy the WAL into the database and cut it to nothing: the space the WAL held comes back.
  sqlite3_exec(db_, "PRAGMA wal_checkpoint(TRUNCATE)", nullptr, nullptr, nullptr);
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "job_store.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "job_row.h"
#include "job_summary.h"
#include "sqlite_util.h"

namespace tessera::server {

namespace fs = std::filesystem;

JobStore::JobStore(const fs::path& data_dir, std::chrono::milliseconds commit_window)
    : dir_(data_dir), db_path_(data_dir / "tessera.db"), reserve_(data_dir / ".reserve"),
      commit_window_(std::max(commit_window, std::chrono::milliseconds(0))) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec || !fs::is_directory(dir_)) {
    throw StoreError("cannot create the data directory " + dir_.string() + ": " +
                     (ec ? ec.message() : std::string("not a directory")));
  }
  check_writable();
  refuse_lost_database();
  reserve_.make();
  // A constructor that throws runs no destructor: close what was opened before passing the
  // refusal on (LeakSanitizer caught the SQLite connection leaking on a corrupt database).
  try {
    open_database();
    try {
      tiles_ = std::make_unique<TileStore>(dir_ / "tiles");
      // A segment number a row ever held is never used again, even if its file (or its row) is gone.
      tiles_->reserve_above(segment_high_water());
    } catch (const StoreError&) {
      throw;
    } catch (const std::exception& e) {
      throw StoreError(e.what());
    }
  } catch (...) {
    close_handles();
    throw;
  }
  writer_ = std::thread([this] { writer_loop(); });
}

void JobStore::check_writable() {
  // Fail now, with the reason, rather than at the first finished tile. (A fixed name: a probe
  // left by a crash is simply written over by the next start.)
  const fs::path probe = dir_ / ".write-test";
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0 || ::write(fd, "x", 1) != 1 || ::fsync(fd) != 0) {
    const int err = errno;
    if (fd >= 0) ::close(fd);
    ::unlink(probe.c_str());
    // A full disk is not a broken one: start and serve what is stored (clients can still fetch
    // and acknowledge frames, which frees space); the first write that fails marks the store
    // unhealthy, and new jobs are refused until then.
    if (err != ENOSPC && err != EDQUOT) {
      throw StoreError("the data directory " + dir_.string() + " is not writable: " + std::strerror(err));
    }
    spdlog::warn("the data directory {} is full ({}): serving what it holds; new jobs are refused until space is "
                 "freed",
                 dir_.string(), std::strerror(err));
  } else {
    ::close(fd);
  }
  ::unlink(probe.c_str());
}

void JobStore::close_handles() {
  for (sqlite3_stmt* st : stmts_) sqlite3_finalize(st);
  stmts_.clear();
  if (read_db_) sqlite3_close(read_db_);
  if (db_) sqlite3_close(db_);
  read_db_ = nullptr;
  db_ = nullptr;
}

JobStore::~JobStore() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (writer_.joinable()) writer_.join();
  close_handles();
}

void JobStore::exec(const char* sql) { exec_sql(db_, db_path_.string(), sql); }

sqlite3_stmt* JobStore::prepare(const char* sql) {
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db_, sql, -1, &st, nullptr) != SQLITE_OK) {
    throw StoreError(db_path_.string() + ": cannot prepare '" + sql + "': " + sqlite3_errmsg(db_));
  }
  stmts_.push_back(st);
  return st;
}

void JobStore::open_database() {
  const std::string db = db_path_.string();
  if (sqlite3_open_v2(db.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr) !=
      SQLITE_OK) {
    throw StoreError("cannot open the database " + db + ": " + (db_ ? sqlite3_errmsg(db_) : "out of memory"));
  }
  sqlite3_busy_timeout(db_, 5000);
  // Keep the -wal and -shm files when the coordinator stops: a restart then needs no new disk
  // space to open the database (SQLite would otherwise recreate both, and fail on a full disk).
  // They are reused, never grown, by the next run.
  int persist = 1;
  sqlite3_file_control(db_, nullptr, SQLITE_FCNTL_PERSIST_WAL, &persist);
  try {
    check_database_integrity(db_, db);  // before anything is written to it
    set_journal_mode(db_, db);
    create_or_migrate_schema(db_, db);
  } catch (const StoreError&) {
    throw;
  } catch (const std::exception& e) {
    throw StoreError(e.what());
  }
  prepare_statements();
  if (sqlite3_open_v2(db.c_str(), &read_db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
    throw StoreError("cannot open the database " + db + " for reading: " + sqlite3_errmsg(read_db_));
  }
  sqlite3_file_control(read_db_, nullptr, SQLITE_FCNTL_PERSIST_WAL, &persist);
  sqlite3_busy_timeout(read_db_, 5000);
}

void JobStore::prepare_statements() {
  ins_job_ = prepare(kInsertJobSql);
  upd_job_ = prepare(kUpdateJobSql);
  ins_tile_ = prepare(
      "INSERT OR REPLACE INTO tiles(job, frame, tile, rays, seconds, segment, offset, length) "
      "VALUES(?1,?2,?3,?4,?5,?6,?7,?8)");
  ins_ack_ = prepare("INSERT OR IGNORE INTO acked_frames(job, frame) VALUES(?1,?2)");
  ins_lease_ = prepare("INSERT OR REPLACE INTO leases(id, worker, job, frame, tile, issued) VALUES(?1,?2,?3,?4,?5,?6)");
  del_lease_ = prepare("DELETE FROM leases WHERE id=?1");
  evict_ = prepare("UPDATE jobs SET resident=0 WHERE id=?1");
  ins_block_ = prepare("INSERT OR IGNORE INTO blocklist(job, worker) VALUES(?1,?2)");
  set_hwm_ = prepare("INSERT OR REPLACE INTO meta(key, value) VALUES('lease_hwm', ?1)");
}

std::optional<JobSnapshot> JobStore::read_job(const JobId& id) {
  std::lock_guard lock(read_mu_);
  // One read transaction: the rows and the summary as one commit left them (the writer may be
  // shedding this job's rows meanwhile).
  if (sqlite3_exec(read_db_, "BEGIN", nullptr, nullptr, nullptr) != SQLITE_OK) return std::nullopt;
  std::optional<JobSnapshot> s;
  try {
    s = read_job_in_transaction(id);
  } catch (const std::exception& e) {
    spdlog::warn("cannot read job {} from {}: {}", id, db_path_.string(), e.what());
    s.reset();
  }
  sqlite3_exec(read_db_, "COMMIT", nullptr, nullptr, nullptr);
  return s;
}

std::optional<JobSnapshot> JobStore::read_job_in_transaction(const JobId& id) {
  sqlite3_stmt* st = nullptr;
  const std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id=?1";
  if (sqlite3_prepare_v2(read_db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) return std::nullopt;
  bind_text(st, 1, id);
  std::optional<JobSnapshot> s;
  if (sqlite3_step(st) == SQLITE_ROW) s = read_job_row(st);
  sqlite3_finalize(st);
  if (!s) return s;
  const std::string name = db_path_.string();
  std::optional<JobSummary> done = read_job_summary(read_db_, name, id);
  if (!done) done = count_job_summary(read_db_, name, id, s->tiles_per_frame);
  s->tiles_done = done->tiles_done;
  s->frames_done = std::move(done->frames_done);
  s->frames_acknowledged = std::move(done->frames_acknowledged);
  if (sqlite3_prepare_v2(read_db_, "SELECT worker FROM blocklist WHERE job=?1 ORDER BY worker", -1, &st, nullptr) ==
      SQLITE_OK) {
    bind_text(st, 1, id);
    while (sqlite3_step(st) == SQLITE_ROW) s->blocklisted.push_back(column_text(st, 0));
    sqlite3_finalize(st);
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// The queue's front: the coordinator's calls, under its mutex; the writer thread does the rest.

void JobStore::push(Op op) {
  bool wake;
  {
    std::lock_guard lock(mu_);
    const bool barrier = std::holds_alternative<Barrier>(op);
    // The first write of a window wakes the writer; the rest join its batch without a wake-up
    // (a writer busy applying the previous batch sees them when it next looks at the queue).
    wake = queue_.empty() || barrier || queue_.size() + 1 >= kMaxBatchOps;
    barrier_queued_ = barrier_queued_ || barrier;
    queue_.push_back(std::move(op));
  }
  if (wake) cv_.notify_one();
}

void JobStore::job_submitted(const JobSnapshot& s) { push(JobRow{s, true}); }
void JobStore::job_updated(const JobSnapshot& s) { push(JobRow{s, false}); }
void JobStore::tile_done(const TileKey& key, const TileOutput& out) {
  push(TileDone{key, out.payload, out.rays, out.seconds});
}
void JobStore::frame_acknowledged(const JobId& job, int frame, int tiles) { push(FrameAck{job, frame, tiles}); }
void JobStore::lease_issued(const Lease& l, const std::string& worker) {
  push(LeaseIssued{l.id, worker, l.tile, to_unix_seconds(l.issued)});
}
void JobStore::lease_ended(LeaseId id) { push(LeaseEnded{id}); }
void JobStore::job_evicted(const JobId& job) { push(Evicted{job}); }
void JobStore::worker_blocklisted(const JobId& job, const std::string& worker) { push(Blocklisted{job, worker}); }

std::future<std::string> JobStore::barrier() {
  auto p = std::make_shared<std::promise<std::string>>();
  auto f = p->get_future();
  push(Barrier{p});
  return f;
}

bool JobStore::healthy() const {
  std::lock_guard lock(mu_);
  return healthy_;
}
std::string JobStore::last_error() const {
  std::lock_guard lock(mu_);
  return last_error_;
}
JobStore::Stats JobStore::stats() const {
  std::lock_guard lock(mu_);
  Stats s = stats_;
  s.queued = queue_.size();
  s.jobs_to_shed = to_shed_.size();
  return s;
}

void JobStore::set_batch_observer(BatchObserver observer) {
  std::lock_guard lock(observer_mu_);
  batch_observer_ = std::move(observer);
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// The coordinator's durable state: jobs, tile states, acknowledged frames and leases in SQLite
// (<data-dir>/tessera.db, WAL mode, synchronous=FULL), finished tile pixels in a TileStore
// (<data-dir>/tiles/<n>.seg, batches appended to one open segment of up to 64 MiB). The database
// is the source of truth at restart.
//
// Writes are asynchronous and batched (group commit): the coordinator queues operations under
// its mutex (cheap: a shared_ptr to the tile bytes), and one writer thread applies everything
// queued so far as a single batch:
//   1. append the batch's tiles to the open segment (one write), fdatasync it (and fsync the
//      directory when the segment is new);
//   2. one SQLite transaction for every row of the batch (a tile row holds its segment, offset
//      and length), in queue order;
//   3. after the commit, delete every segment whose records all belong to acknowledged frames or
//      evicted jobs (a segment with one unacknowledged frame left stays whole).
// So a tile is marked done in SQLite only after its bytes are durable, and a committed prefix of
// the queue is always a consistent state. A failed batch (full disk, I/O error) is rolled back,
// marks the store unhealthy (submit answers RESOURCE_EXHAUSTED) and is retried every second, in
// order, until it succeeds. barrier() tells a caller when everything queued before it is durable.
//
// After each batch, and whenever nothing is queued, the writer sheds the rows of evicted jobs
// (their tile, acknowledged-frame and lease rows; the job's own row stays, with a summary of what
// it did, job_summary.h), whole frames of about kShedChunkRows tile rows a transaction, the
// summary in the first: the database grows with the jobs in memory, not with every tile ever
// rendered, and a crash between two chunks leaves a job that answers from its summary.
//
// The writer waits a commit window (default 1 s) after the first write of a batch before it
// applies it, so that one fdatasync and one commit serve every tile finished meanwhile rather
// than each tile paying for its own (with one worker a tile took two syncs, a SQLite commit and a
// writer wake-up: most of the coordinator's CPU per tile; at 20 ms the syncs alone still took a
// third of it). Only the first write of a window wakes the writer. A barrier ends the window at
// once (a client waiting on a submit is not made to wait), as does a full batch. The window is
// how much longer a finished tile may stay only in memory; a crash in it loses nothing a client
// was promised: the tile is rendered again.
//
// The class in files: job_store.cpp (opening the store, the queue's front), job_store_recovery.cpp
// (reading the state back at start), job_store_writer.cpp (the group-commit writer),
// job_store_shedding.cpp (the rows of evicted jobs shed). Its parts: job_store_schema.h (the
// tables and versions), job_row.h (a jobs row), job_summary.h (an evicted job's summary),
// tile_store.h (segment files), segment_ledger.h (which segments are still needed),
// disk_reserve.h (space for SQLite).
#pragma once

#include <sqlite3.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "disk_reserve.h"
#include "job_store_schema.h"
#include "job_store_stats.h"
#include "scheduler.h"
#include "segment_ledger.h"
#include "tile_store.h"

namespace tessera::server {

// Cannot open the data directory or the database: the message names the file and the problem.
struct StoreError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class JobStore {
 public:
  static constexpr int kSchemaVersion = kStoreSchemaVersion;  // job_store_schema.h: the versions

  // Opens or creates the store; checks the directory is writable, the database's integrity
  // (PRAGMA quick_check) and its schema version. Throws StoreError.
  static constexpr std::chrono::milliseconds kDefaultCommitWindow{1000};
  static constexpr size_t kMaxBatchOps = 4096;  // a batch this full is applied without waiting out its window
  static constexpr int kShedChunkRows = 8192;    // tile rows of evicted jobs shed a transaction (whole frames)
  explicit JobStore(const std::filesystem::path& data_dir,
                    std::chrono::milliseconds commit_window = kDefaultCommitWindow);
  ~JobStore();  // writes everything still queued, then stops the writer
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  struct Loaded {
    std::vector<JobRecord> jobs;      // resident jobs, in submit order
    LeaseId next_lease = 1;
    int64_t leases_requeued = 0;      // leases in flight at the last stop
    int64_t tiles_missing = 0;        // done rows whose record was unreadable, damaged or another
                                      // tile's: dropped, so the tile is rendered again
    int64_t orphans_removed = 0;      // files in tiles/ no committed row needs (segments of a crash
                                      // before the commit, or of acknowledged frames)
  };
  // Is a stored tile's payload the tile its row names? "" when it is, else what it is instead
  // (e.g. "it is job J frame F tile T"). Payloads are opaque here; the coordinator, which knows
  // their format, supplies the check. Without it only the record's length and CRC are checked.
  using TileCheck = std::function<std::string(const TileKey& row, const std::string& payload)>;
  // Reads the state back (call once, before any write). Leases in flight at the last stop come
  // back as queued tiles; a done row whose record is unreadable, damaged or another tile's is
  // dropped (the tile is rendered again); orphan segments (and any other file in tiles/) are
  // removed. Evicted jobs whose rows are not all shed yet (a stop came first) are shed again.
  Loaded load(const TileCheck& check = {});

  // --- writes (queued; applied in order by the writer thread) ---------------------------------
  void job_submitted(const JobSnapshot& s);
  void job_updated(const JobSnapshot& s);  // state, error, counters
  void tile_done(const TileKey& key, const TileOutput& out);
  void frame_acknowledged(const JobId& job, int frame, int tiles_per_frame);
  void lease_issued(const Lease& lease, const std::string& worker_name);
  void lease_ended(LeaseId id);
  void job_evicted(const JobId& job);  // left coordinator memory: its tiles are released
  void worker_blocklisted(const JobId& job, const std::string& worker);  // by worker name
  // Resolved with "" once every write queued before it is committed, or with the error of the
  // batch that failed.
  std::future<std::string> barrier();

  bool healthy() const;
  std::string last_error() const;
  const std::filesystem::path& db_path() const { return db_path_; }

  // An evicted job, read from SQLite (for status queries): from its rows, or from its summary
  // once they are shed (the same answer). Runs on the caller's thread.
  std::optional<JobSnapshot> read_job(const JobId& id);

  using Stats = JobStoreStats;  // job_store_stats.h
  Stats stats() const;
  // Called by the writer thread after each batch it committed: how long the batch took (segment
  // write, fsyncs, SQLite commit) and the tile bytes it wrote (the metrics' store latency and
  // bytes, server/metrics). Its owner clears it (an empty observer) before it is destroyed: once
  // set_batch_observer returns, the observer it replaced is not running and is never called
  // again, so the store may write its last batches after the observer is gone.
  using BatchObserver = std::function<void(double seconds, uint64_t tile_bytes)>;
  void set_batch_observer(BatchObserver observer);

 private:
  struct JobRow { JobSnapshot s; bool insert; };
  struct TileDone { TileKey key; std::shared_ptr<const std::string> payload; uint64_t rays; double seconds; };
  struct FrameAck { JobId job; int frame; int tiles; };
  struct LeaseIssued { LeaseId id; std::string worker; TileKey tile; double issued; };
  struct LeaseEnded { LeaseId id; };
  struct Evicted { JobId job; };
  struct Blocklisted { JobId job; std::string worker; };
  struct Barrier { std::shared_ptr<std::promise<std::string>> done; };
  using Op = std::variant<JobRow, TileDone, FrameAck, LeaseIssued, LeaseEnded, Evicted, Blocklisted, Barrier>;
  using FrameKey = SegmentLedger::FrameKey;
  struct BatchPlan;  // job_store_writer.cpp

  // --- opening (job_store.cpp) ------------------------------------------------------------------
  void check_writable();  // logs a full disk; throws StoreError for any other failure
  void open_database();
  void prepare_statements();
  void exec(const char* sql);
  sqlite3_stmt* prepare(const char* sql);
  void close_handles();  // finalizes statements and closes both connections (idempotent)
  std::optional<JobSnapshot> read_job_in_transaction(const JobId& id);  // read_job's, under read_mu_

  // --- reading back at start (job_store_recovery.cpp) -------------------------------------------
  // Throws when the database is missing or empty but the directory holds tiles it described.
  void refuse_lost_database();
  // Runs `sql` on the writer's connection, calling `row` for each row; throws StoreError.
  void query(const std::string& sql, const std::function<void(sqlite3_stmt*)>& row);
  void load_lease_marks(Loaded& out);
  // The job's done tiles, with the pixels of those of unacknowledged frames; a tile whose
  // record is unusable is left out and added to `missing`.
  void load_done_tiles(JobRecord& r, const std::set<int>& acked, const TileCheck& check,
                       std::vector<TileKey>& missing, Loaded& out);
  // Deletes the rows of `missing` tiles and every lease row (best effort: see the .cpp).
  void drop_stale_rows(const std::vector<TileKey>& missing);
  // Deletes everything in tiles/ that no loaded tile needs; returns the number of files.
  int64_t remove_orphans();

  // --- writing (job_store_writer.cpp) -----------------------------------------------------------
  void push(Op op);
  void writer_loop();
  // Applies `pending`, and on failure what of it needs no new segment (see apply()); returns
  // the error ("" once everything is committed) and leaves in `deferred` the tiles still to write.
  std::string apply_pending(std::vector<Op>& pending, std::vector<Op>& deferred);
  void report_batch(double seconds, const std::vector<Op>& batch);  // to the batch observer, if any
  // Applies the batch; throws on failure (the transaction is rolled back). With `new_segment`
  // false, tiles that would need one (tiles of frames not acknowledged in this batch) are left
  // out and returned, to be retried: the rest (acknowledgements, whose commit frees segments,
  // evictions, job and lease rows) must not wait behind writes a full disk cannot take.
  std::vector<Op> apply(std::vector<Op>& batch, bool new_segment = true);
  BatchPlan plan_batch(const std::vector<Op>& batch, bool new_segment) const;
  void write_pixels(const std::vector<Op>& batch, BatchPlan& plan);
  void commit_rows(const std::vector<Op>& batch, const BatchPlan& plan);
  void write_row(const Op& op, const BatchPlan& plan, size_t& next_at);
  void step(sqlite3_stmt* st);
  std::vector<Op> release_delivered(const std::vector<Op>& batch, const BatchPlan& plan);
  // Full disk, SQLite included: deletes now the segments the queued acknowledgements and
  // evictions will free once committed (see the .cpp for the crash trade-off).
  void reclaim_delivered(const std::vector<Op>& pending);
  void release_reserve();  // and checkpoint the WAL (TRUNCATE)

  // --- shedding the rows of evicted jobs (job_store_shedding.cpp) -------------------------------
  // The writer sheds the job's rows next (it may start at once: the caller uses the writer's
  // connection no more).
  void queue_shedding(const JobId& job);
  // Evicted jobs that still have rows (at start: the rows a stop or a version 3 database left).
  std::vector<JobId> unshed_jobs();
  // One transaction: the next chunk of the first job's rows (see the header). Writer thread.
  void shed_chunk();
  // Deletes up to kShedChunkRows tile rows of `job` (its summary first, the first time); true
  // when none is left, and then its other rows are gone too. In the caller's transaction.
  bool shed_rows_of(const JobId& job);
  int64_t segment_high_water();  // the highest segment number a row ever held
  std::filesystem::path dir_, db_path_;
  DiskReserve reserve_;       // writer thread only (and the constructor)
  SegmentLedger segments_;    // writer thread only (and load(), before it runs)
  std::unique_ptr<TileStore> tiles_;
  sqlite3* db_ = nullptr;      // the writer's connection (and load()'s, before the writer runs)
  sqlite3* read_db_ = nullptr; // read_job()'s connection (WAL: readers do not block the writer)
  std::mutex read_mu_;
  std::vector<sqlite3_stmt*> stmts_;
  sqlite3_stmt *ins_job_ = nullptr, *upd_job_ = nullptr, *ins_tile_ = nullptr, *ins_ack_ = nullptr,
               *ins_lease_ = nullptr, *del_lease_ = nullptr, *evict_ = nullptr, *set_hwm_ = nullptr,
               *ins_block_ = nullptr;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Op> queue_;
  bool stopping_ = false;
  bool barrier_queued_ = false;  // ends the commit window early
  const std::chrono::milliseconds commit_window_;
  bool healthy_ = true;
  std::string last_error_;
  Stats stats_;
  std::mutex observer_mu_;  // held while the observer runs: clearing it waits for that call
  BatchObserver batch_observer_;  // under observer_mu_
  std::deque<JobId> to_shed_;  // under mu_: evicted jobs whose rows are shed next, in order
  bool shed_failing_ = false;  // writer thread only: shedding waits for the next batch that commits
  LeaseId lease_hwm_ = 0;  // writer thread only
  std::thread writer_;
};

}  // namespace tessera::server

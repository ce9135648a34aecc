// The coordinator's durable state: jobs, tile states, acknowledged frames and leases in SQLite
// (<data-dir>/tessera.db, WAL mode, synchronous=FULL), finished tile pixels in a TileStore
// (<data-dir>/tiles/<n>.seg, one segment file per batch). The database is the source of truth at restart.
//
// Writes are asynchronous and batched (group commit): the coordinator queues operations under
// its mutex (cheap: a shared_ptr to the tile bytes), and one writer thread applies everything
// queued so far as a single batch:
//   1. append the batch's tiles to one new segment file, fdatasync it, fsync the directory;
//   2. one SQLite transaction for every row of the batch (a tile row holds its segment, offset
//      and length), in queue order;
//   3. after the commit, delete every segment whose records all belong to acknowledged frames or
//      evicted jobs (a segment with one unacknowledged frame left stays whole).
// So a tile is marked done in SQLite only after its bytes are durable, and a committed prefix of
// the queue is always a consistent state. A failed batch (full disk, I/O error) is rolled back,
// marks the store unhealthy (submit answers RESOURCE_EXHAUSTED) and is retried every second, in
// order, until it succeeds. barrier() tells a caller when everything queued before it is durable.
#pragma once

#include <sqlite3.h>
#include <sys/types.h>

#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <unordered_map>
#include <variant>
#include <vector>

#include "scheduler.h"
#include "tile_store.h"

namespace tessera::server {

// Cannot open the data directory or the database: the message names the file and the problem.
struct StoreError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class JobStore {
 public:
  // 2: tiles live in segment files (tiles.segment/offset/length). Version 1 (a file per tile) is
  // refused with a message, not migrated: no farm ran it in production.
  static constexpr int kSchemaVersion = 3;  // 3: jobs.owner, blocklist (version 2 is migrated)

  // Opens or creates the store; checks the directory is writable, the database's integrity
  // (PRAGMA quick_check) and its schema version. Throws StoreError.
  explicit JobStore(const std::filesystem::path& data_dir);
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
  // removed.
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

  // An evicted job, read from SQLite (for status queries). Runs on the caller's thread.
  std::optional<JobSnapshot> read_job(const JobId& id);

  struct Stats {
    int64_t batches = 0, ops = 0, failures = 0;
    size_t queued = 0;
  };
  Stats stats() const;
  // Called by the writer thread after each batch it committed: how long the batch took (segment
  // write, fsyncs, SQLite commit) and the tile bytes it wrote. Set before the first write (the
  // metrics' store latency and bytes, issue 16).
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

  void push(Op op);
  void writer_loop();
  // Applies the batch; throws on failure (the transaction is rolled back). With `new_segment`
  // false, tiles that would need one (tiles of frames not acknowledged in this batch) are left
  // out and returned, to be retried: the rest (acknowledgements, whose commit frees segments,
  // evictions, job and lease rows) must not wait behind writes a full disk cannot take.
  std::vector<Op> apply(std::vector<Op>& batch, bool new_segment = true);
  void exec(const char* sql);
  sqlite3_stmt* prepare(const char* sql);
  void open_database();
  // Throws when the database is missing or empty but the directory holds tiles it described.
  void refuse_lost_database();
  void close_handles();  // finalizes statements and closes both connections (idempotent)
  // Segment bookkeeping (writer thread, and load() before it): which segment holds each tile of
  // an unacknowledged frame of a resident job, and how many such tiles each segment holds. A
  // segment whose count drops to zero is deleted; rows of acknowledged frames keep their (dead)
  // location, which is never read.
  using FrameKey = std::pair<JobId, int>;
  void track_tile(const TileKey& key, int64_t segment);
  void release_frame(const FrameKey& frame, std::vector<int64_t>& emptied);
  void release_job(const JobId& job, std::vector<int64_t>& emptied);
  // Full disk, SQLite included: deletes now the segments the queued acknowledgements and
  // evictions will free once committed (see the .cpp for the crash trade-off).
  void reclaim_delivered(const std::vector<Op>& pending);
  // <data-dir>/.reserve: space held back for SQLite on a full disk (see the .cpp).
  static constexpr off_t kReserveBytes = 512 * 1024;
  void make_reserve();
  void release_reserve();  // and checkpoint the WAL (TRUNCATE)
  bool reserve_wanted_ = false;  // writer thread only (and the constructor)
  std::map<FrameKey, std::map<int, int64_t>> frame_tiles_;
  std::unordered_map<int64_t, int64_t> segment_live_;

  std::filesystem::path dir_, db_path_;
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
  bool healthy_ = true;
  std::string last_error_;
  Stats stats_;
  BatchObserver batch_observer_;  // under mu_ (the writer copies it with each batch)
  LeaseId lease_hwm_ = 0;  // writer thread only
  std::thread writer_;
};

// Steady-clock time points <-> Unix seconds (what the database stores).
double to_unix_seconds(TimePoint t);
TimePoint from_unix_seconds(double unix_s);

}  // namespace tessera::server

#include "job_store.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <unordered_set>

namespace tessera::server {

namespace fs = std::filesystem;

double to_unix_seconds(TimePoint t) {
  const auto sys = std::chrono::system_clock::now() - std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                                          Clock::now() - t);
  return std::chrono::duration<double>(sys.time_since_epoch()).count();
}

TimePoint from_unix_seconds(double unix_s) {
  const double now_unix = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  return Clock::now() - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(now_unix - unix_s));
}

namespace {

const char* kSchema = R"sql(
CREATE TABLE schema_version(version INTEGER NOT NULL);
CREATE TABLE meta(key TEXT PRIMARY KEY, value INTEGER NOT NULL);
CREATE TABLE jobs(
  id TEXT PRIMARY KEY, seq INTEGER NOT NULL, name TEXT NOT NULL, bundle TEXT NOT NULL, overrides BLOB NOT NULL,
  first_frame INTEGER NOT NULL, last_frame INTEGER NOT NULL, width INTEGER NOT NULL, height INTEGER NOT NULL,
  spp INTEGER NOT NULL, tile_size INTEGER NOT NULL, priority INTEGER NOT NULL,
  state TEXT NOT NULL, error TEXT NOT NULL DEFAULT '', submitted REAL NOT NULL, ended REAL,
  duplicates INTEGER NOT NULL DEFAULT 0, rays INTEGER NOT NULL DEFAULT 0,
  resident INTEGER NOT NULL DEFAULT 1, owner TEXT NOT NULL DEFAULT '');
-- A row per finished tile; its pixels are the record at byte `offset` of tiles/<segment>.seg
-- (payload `length` bytes) until the frame is acknowledged. Tiles without a row are queued (or
-- were leased when the coordinator stopped).
CREATE TABLE tiles(job TEXT NOT NULL, frame INTEGER NOT NULL, tile INTEGER NOT NULL, rays INTEGER NOT NULL,
  seconds REAL NOT NULL, segment INTEGER NOT NULL, offset INTEGER NOT NULL, length INTEGER NOT NULL,
  PRIMARY KEY(job, frame, tile)) WITHOUT ROWID;
CREATE TABLE acked_frames(job TEXT NOT NULL, frame INTEGER NOT NULL, PRIMARY KEY(job, frame)) WITHOUT ROWID;
CREATE TABLE leases(id INTEGER PRIMARY KEY, worker TEXT NOT NULL, job TEXT NOT NULL, frame INTEGER NOT NULL,
  tile INTEGER NOT NULL, issued REAL NOT NULL);
-- Workers (by name) that get no more tiles of a job after --max-faults bad results.
CREATE TABLE blocklist(job TEXT NOT NULL, worker TEXT NOT NULL, PRIMARY KEY(job, worker)) WITHOUT ROWID;
)sql";

std::optional<JobState> parse_state(const std::string& s) {
  for (JobState st : {JobState::kQueued, JobState::kRunning, JobState::kDone, JobState::kCancelled, JobState::kFailed}) {
    if (s == job_state_name(st)) return st;
  }
  return std::nullopt;
}

std::string text(sqlite3_stmt* st, int col) {
  const auto* p = sqlite3_column_text(st, col);
  return p ? std::string(reinterpret_cast<const char*>(p), size_t(sqlite3_column_bytes(st, col))) : std::string();
}

std::string blob(sqlite3_stmt* st, int col) {
  const void* p = sqlite3_column_blob(st, col);
  return p ? std::string(static_cast<const char*>(p), size_t(sqlite3_column_bytes(st, col))) : std::string();
}

// The columns read by read_row(), in this order.
constexpr const char* kJobColumns =
    "id, seq, name, bundle, overrides, first_frame, last_frame, width, height, spp, tile_size, priority, state, "
    "error, submitted, ended, duplicates, rays, owner";

JobSnapshot read_row(sqlite3_stmt* st) {
  JobSnapshot s;
  s.id = text(st, 0);
  s.seq = uint64_t(sqlite3_column_int64(st, 1));
  s.spec.name = text(st, 2);
  s.spec.bundle_sha256 = text(st, 3);
  s.spec.overrides = blob(st, 4);
  s.spec.first_frame = sqlite3_column_int(st, 5);
  s.spec.last_frame = sqlite3_column_int(st, 6);
  s.spec.width = sqlite3_column_int(st, 7);
  s.spec.height = sqlite3_column_int(st, 8);
  s.spec.spp = sqlite3_column_int(st, 9);
  s.spec.tile_size = std::max(1, sqlite3_column_int(st, 10));
  s.spec.priority = sqlite3_column_int(st, 11);
  const std::string state = text(st, 12);
  s.state = parse_state(state).value_or(JobState::kFailed);
  s.error = text(st, 13);
  if (!parse_state(state)) s.error = "unknown state '" + state + "' in the database";
  s.submitted = from_unix_seconds(sqlite3_column_double(st, 14));
  if (sqlite3_column_type(st, 15) != SQLITE_NULL) s.ended = from_unix_seconds(sqlite3_column_double(st, 15));
  s.duplicates_discarded = sqlite3_column_int64(st, 16);
  s.rays = uint64_t(sqlite3_column_int64(st, 17));
  s.spec.owner = text(st, 18);
  const int ts = s.spec.tile_size;
  s.tiles_per_frame = ((s.spec.width + ts - 1) / ts) * ((s.spec.height + ts - 1) / ts);
  s.tiles_total = int64_t(s.spec.last_frame - s.spec.first_frame + 1) * s.tiles_per_frame;
  return s;
}

}  // namespace

JobStore::JobStore(const fs::path& data_dir) : dir_(data_dir), db_path_(data_dir / "tessera.db") {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec || !fs::is_directory(dir_)) {
    throw StoreError("cannot create the data directory " + dir_.string() + ": " +
                     (ec ? ec.message() : std::string("not a directory")));
  }
  // Fail now, with the reason, rather than at the first finished tile.
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
  refuse_lost_database();
  make_reserve();
  // A constructor that throws runs no destructor: close what was opened before passing the
  // refusal on (LeakSanitizer caught the SQLite connection leaking on a corrupt database).
  try {
    open_database();
    try {
      tiles_ = std::make_unique<TileStore>(dir_ / "tiles");
      // A segment number a row ever held is never used again, even if its file is gone.
      sqlite3_stmt* st = prepare("SELECT coalesce(max(segment), 0) FROM tiles");
      if (sqlite3_step(st) == SQLITE_ROW) tiles_->reserve_above(sqlite3_column_int64(st, 0));
      sqlite3_reset(st);
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

void JobStore::refuse_lost_database() {
  // SQLite takes a missing or 0-byte file for a new, empty database. For a new farm that is
  // right; but when tiles/ still holds segments (or a write-ahead log is left), the database
  // that described them was lost or truncated, and starting would take every segment for an
  // orphan and delete it: the farm's finished work, wiped without a word. Refuse instead.
  std::error_code ec;
  const bool exists = fs::exists(db_path_, ec);
  const auto size = exists ? fs::file_size(db_path_, ec) : 0;
  if (exists && (ec || size > 0)) return;
  std::vector<std::string> claimed;
  int64_t tile_files = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "tiles", ec)) {
    (void)e;
    ++tile_files;
  }
  if (tile_files > 0) claimed.push_back((dir_ / "tiles").string() + " holds " + std::to_string(tile_files) + " files");
  const fs::path wal = db_path_.string() + "-wal";
  if (fs::exists(wal, ec) && fs::file_size(wal, ec) > 0 && !ec) claimed.push_back(wal.string() + " is not empty");
  if (claimed.empty()) return;  // nothing a database could claim: a new farm
  std::string what;
  for (const auto& c : claimed) what += (what.empty() ? "" : " and ") + c;
  throw StoreError("the database " + db_path_.string() + (exists ? " is empty (0 bytes)" : " is missing") + " but " +
                   what + ": this is not a new farm, and starting would delete its finished tiles as orphans. "
                   "Restore the database from a backup, or move " + dir_.string() +
                   " away (or use another --data-dir) to start a new farm");
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

void JobStore::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : sqlite3_errmsg(db_);
    sqlite3_free(err);
    throw std::runtime_error(db_path_.string() + ": " + msg);
  }
}

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
  // space to open the database (SQLite would otherwise recreate both, and fail on a full disk:
  // issue 15, defect 7). They are reused, never grown, by the next run.
  int persist = 1;
  sqlite3_file_control(db_, nullptr, SQLITE_FCNTL_PERSIST_WAL, &persist);
  // Integrity first: a file that is not a database, or a damaged one, stops the coordinator here
  // with the file's name, instead of losing jobs later.
  {
    sqlite3_stmt* st = nullptr;
    int rc = sqlite3_prepare_v2(db_, "PRAGMA quick_check", -1, &st, nullptr);
    std::vector<std::string> problems;
    if (rc == SQLITE_OK) {
      while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
        const std::string row = text(st, 0);
        if (row != "ok" && problems.size() < 5) problems.push_back(row);
      }
    }
    const std::string msg = sqlite3_errmsg(db_);
    const int code = sqlite3_extended_errcode(db_) & 0xff;
    sqlite3_finalize(st);
    // The file could not be read at all (disk full, I/O error, permissions): say so, rather
    // than call a good database corrupt.
    if (rc != SQLITE_DONE && code != SQLITE_NOTADB && code != SQLITE_CORRUPT) {
      throw StoreError("cannot read the database " + db + " (" + msg +
                       "): check the disk holding it (full, read-only, failing?)");
    }
    if (rc != SQLITE_DONE) {
      throw StoreError("the database " + db + " is unreadable (" + msg +
                       "): it is corrupt or not a Tessera database. Move it away (the coordinator then starts "
                       "with no jobs) or restore a backup");
    }
    if (!problems.empty()) {
      std::string all;
      for (const auto& p : problems) all += (all.empty() ? "" : "; ") + p;
      throw StoreError("the database " + db + " failed its integrity check: " + all +
                       ". Move it away (the coordinator then starts with no jobs) or restore a backup");
    }
  }
  try {
    exec("PRAGMA journal_mode=WAL");
    // FULL: a commit is on disk when it returns (one fsync of the WAL per batch).
    exec("PRAGMA synchronous=FULL");
    // A bounded WAL: checkpoint every 256 pages (1 MiB) and cut the file back to 1 MiB after a
    // checkpoint. SQLite's default (1000 pages, never cut back) let the WAL alone grow to fill
    // a small data disk.
    exec("PRAGMA wal_autocheckpoint=256");
    exec("PRAGMA journal_size_limit=1048576");
    bool has_schema = false;
    {
      sqlite3_stmt* st = nullptr;
      sqlite3_prepare_v2(db_, "SELECT count(*) FROM sqlite_master WHERE type='table' AND name='schema_version'", -1,
                         &st, nullptr);
      if (sqlite3_step(st) == SQLITE_ROW) has_schema = sqlite3_column_int(st, 0) > 0;
      sqlite3_finalize(st);
    }
    if (!has_schema) {
      int tables = 0;
      sqlite3_stmt* st = nullptr;
      sqlite3_prepare_v2(db_, "SELECT count(*) FROM sqlite_master", -1, &st, nullptr);
      if (sqlite3_step(st) == SQLITE_ROW) tables = sqlite3_column_int(st, 0);
      sqlite3_finalize(st);
      if (tables > 0) {
        throw StoreError("the database " + db + " is an SQLite database but not a Tessera one (no schema_version "
                         "table): use another --data-dir");
      }
      exec("BEGIN");
      exec(kSchema);
      exec(("INSERT INTO schema_version VALUES (" + std::to_string(kSchemaVersion) + ")").c_str());
      exec("COMMIT");
    } else {
      sqlite3_stmt* st = nullptr;
      sqlite3_prepare_v2(db_, "SELECT version FROM schema_version", -1, &st, nullptr);
      int version = -1;
      if (sqlite3_step(st) == SQLITE_ROW) version = sqlite3_column_int(st, 0);
      sqlite3_finalize(st);
      if (version == 1) {
        throw StoreError("the database " + db + " has schema version 1 (a file per tile under tiles/<job>/); this "
                         "tessera-server reads version " + std::to_string(kSchemaVersion) +
                         " (tiles in segment files) and does not migrate it. Let the old tessera-server finish "
                         "its jobs, or start with another --data-dir");
      }
      if (version == 2) {
        // Version 3 added jobs.owner (the per-client job quota survives a restart) and the
        // blocklist table (so do blocklists). Jobs stored by version 2 have no owner: they count
        // for no client, as before; and no blocklist.
        exec("BEGIN");
        exec("ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT ''");
        exec("CREATE TABLE blocklist(job TEXT NOT NULL, worker TEXT NOT NULL, PRIMARY KEY(job, worker)) WITHOUT ROWID");
        exec(("UPDATE schema_version SET version=" + std::to_string(kSchemaVersion)).c_str());
        exec("COMMIT");
        spdlog::info("database {}: migrated schema version 2 to {}", db, kSchemaVersion);
        version = kSchemaVersion;
      }
      if (version != kSchemaVersion) {
        throw StoreError("the database " + db + " has schema version " + std::to_string(version) +
                         "; this tessera-server reads version " + std::to_string(kSchemaVersion) +
                         ". Use the tessera-server that wrote it, or another --data-dir");
      }
    }
  } catch (const StoreError&) {
    throw;
  } catch (const std::exception& e) {
    throw StoreError(e.what());
  }
  ins_job_ = prepare(
      "INSERT OR REPLACE INTO jobs(id, seq, name, bundle, overrides, first_frame, last_frame, width, height, spp, "
      "tile_size, priority, state, error, submitted, ended, duplicates, rays, owner) "
      "VALUES(?1,?2,?3,?4,?5,?6,?7,?8,?9,?10,?11,?12,?13,?14,?15,?16,?17,?18,?19)");
  // priority: SetJobPriority changes it (issue 16).
  upd_job_ = prepare("UPDATE jobs SET state=?2, error=?3, ended=?4, duplicates=?5, rays=?6, priority=?7 WHERE id=?1");
  ins_tile_ = prepare(
      "INSERT OR REPLACE INTO tiles(job, frame, tile, rays, seconds, segment, offset, length) "
      "VALUES(?1,?2,?3,?4,?5,?6,?7,?8)");
  ins_ack_ = prepare("INSERT OR IGNORE INTO acked_frames(job, frame) VALUES(?1,?2)");
  ins_lease_ = prepare("INSERT OR REPLACE INTO leases(id, worker, job, frame, tile, issued) VALUES(?1,?2,?3,?4,?5,?6)");
  del_lease_ = prepare("DELETE FROM leases WHERE id=?1");
  evict_ = prepare("UPDATE jobs SET resident=0 WHERE id=?1");
  ins_block_ = prepare("INSERT OR IGNORE INTO blocklist(job, worker) VALUES(?1,?2)");
  set_hwm_ = prepare("INSERT OR REPLACE INTO meta(key, value) VALUES('lease_hwm', ?1)");
  if (sqlite3_open_v2(db.c_str(), &read_db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
    throw StoreError("cannot open the database " + db + " for reading: " + sqlite3_errmsg(read_db_));
  }
  sqlite3_file_control(read_db_, nullptr, SQLITE_FCNTL_PERSIST_WAL, &persist);
  sqlite3_busy_timeout(read_db_, 5000);
}

// ---------------------------------------------------------------------------------------------
// Loading

JobStore::Loaded JobStore::load(const TileCheck& check) {
  Loaded out;
  auto query = [&](const std::string& sql, auto&& row) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
      throw StoreError(db_path_.string() + ": " + sqlite3_errmsg(db_));
    }
    int rc;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) row(st);
    sqlite3_finalize(st);
    if (rc != SQLITE_DONE) throw StoreError(db_path_.string() + ": " + sqlite3_errmsg(db_));
  };
  LeaseId hwm = 0;
  query("SELECT value FROM meta WHERE key='lease_hwm'", [&](sqlite3_stmt* st) { hwm = LeaseId(sqlite3_column_int64(st, 0)); });
  query("SELECT count(*), coalesce(max(id), 0) FROM leases", [&](sqlite3_stmt* st) {
    out.leases_requeued = sqlite3_column_int64(st, 0);
    hwm = std::max(hwm, LeaseId(sqlite3_column_int64(st, 1)));
  });
  out.next_lease = hwm + 1;
  lease_hwm_ = hwm;

  std::vector<std::pair<JobId, std::pair<int, int>>> missing;
  std::map<JobId, std::set<int>> acked_by_job;
  frame_tiles_.clear();
  segment_live_.clear();
  query(std::string("SELECT ") + kJobColumns + " FROM jobs WHERE resident=1 ORDER BY seq", [&](sqlite3_stmt* st) {
    JobSnapshot s = read_row(st);
    JobRecord r;
    r.id = s.id;
    r.spec = s.spec;
    r.state = s.state;
    r.error = s.error;
    r.seq = s.seq;
    r.submitted = s.submitted;
    r.ended = s.ended;
    r.duplicates = s.duplicates_discarded;
    out.jobs.push_back(std::move(r));
  });
  for (JobRecord& r : out.jobs) {
    std::set<int>& acked = acked_by_job[r.id];
    query("SELECT frame FROM acked_frames WHERE job='" + r.id + "'", [&](sqlite3_stmt* st) {
      acked.insert(sqlite3_column_int(st, 0));
    });
    r.acknowledged.assign(acked.begin(), acked.end());
    query("SELECT worker FROM blocklist WHERE job='" + r.id + "' ORDER BY worker",
          [&](sqlite3_stmt* st) { r.blocklisted.push_back(text(st, 0)); });
    query("SELECT frame, tile, rays, seconds, segment, offset, length FROM tiles WHERE job='" + r.id +
              "' ORDER BY frame, tile",
          [&](sqlite3_stmt* st) {
            RestoredTile t;
            t.frame = sqlite3_column_int(st, 0);
            t.tile = sqlite3_column_int(st, 1);
            t.output.rays = uint64_t(sqlite3_column_int64(st, 2));
            t.output.seconds = sqlite3_column_double(st, 3);
            const TileStore::Location at{sqlite3_column_int64(st, 4), sqlite3_column_int64(st, 5),
                                         sqlite3_column_int64(st, 6)};
            if (!acked.count(t.frame)) {
              auto got = tiles_->read(at);
              // A record that is intact but holds another tile (segment files swapped or copied
              // over each other) is as wrong as a damaged one: serving it would put another
              // frame's or job's pixels into this frame.
              if (got.bytes && check) {
                if (std::string other = check({r.id, t.frame, t.tile}, *got.bytes); !other.empty()) {
                  got.error = tiles_->segment_path(at.segment).string() + " at offset " + std::to_string(at.offset) +
                              ": the record is not this tile: " + other;
                  got.bytes.reset();
                }
              }
              if (!got.bytes) {
                // Should not happen (the segment is durable before its row); re-render rather than lie.
                spdlog::error("job {} frame {} tile {}: done in {} but its stored pixels are unusable ({}): the tile "
                              "will be rendered again",
                              r.id, t.frame, t.tile, db_path_.string(), got.error);
                missing.push_back({r.id, {t.frame, t.tile}});
                ++out.tiles_missing;
                return;
              }
              t.output.payload = std::make_shared<const std::string>(std::move(*got.bytes));
              track_tile({r.id, t.frame, t.tile}, at.segment);
            }
            r.done.push_back(std::move(t));
          });
  }
  // Dropping the rows of unusable tiles and the leases of the last run: on a full disk these
  // deletions may fail (SQLite needs room to delete); that must not stop the coordinator, and
  // they are repeated at the next start. (Lease rows left behind are only ever read here.)
  try {
    exec("BEGIN");
    for (const auto& [job, ft] : missing) {
      exec(("DELETE FROM tiles WHERE job='" + job + "' AND frame=" + std::to_string(ft.first) +
            " AND tile=" + std::to_string(ft.second))
               .c_str());
    }
    // Leases in flight at the last stop: their tiles are queued again (rows without a done tile).
    exec("DELETE FROM leases");
    exec("COMMIT");
  } catch (const std::exception& e) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    spdlog::warn("cannot clean up the database at start ({}): carrying on; retried at the next start", e.what());
  }
  // Orphans: everything in tiles/ but the segments holding a readable tile of an unacknowledged
  // frame of a resident job. That is segments of a crash between the segment's sync and the
  // commit, of acknowledged frames or evicted jobs whose unlink was interrupted, and any
  // directory left by schema version 1.
  std::error_code ec;
  std::vector<fs::path> doomed;
  for (const auto& e : fs::directory_iterator(tiles_->root(), ec)) {
    const auto n = TileStore::parse_segment_name(e.path().filename().string());
    if (!n || !segment_live_.count(*n)) doomed.push_back(e.path());
  }
  for (const fs::path& p : doomed) {
    std::error_code rec;
    const auto removed = fs::remove_all(p, rec);
    if (removed != static_cast<std::uintmax_t>(-1)) out.orphans_removed += int64_t(removed);
  }
  return out;
}

std::optional<JobSnapshot> JobStore::read_job(const JobId& id) {
  std::lock_guard lock(read_mu_);
  sqlite3_stmt* st = nullptr;
  const std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id=?1";
  if (sqlite3_prepare_v2(read_db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) return std::nullopt;
  sqlite3_bind_text(st, 1, id.c_str(), int(id.size()), SQLITE_TRANSIENT);
  std::optional<JobSnapshot> s;
  if (sqlite3_step(st) == SQLITE_ROW) s = read_row(st);
  sqlite3_finalize(st);
  if (!s) return s;
  if (sqlite3_prepare_v2(read_db_, "SELECT frame, count(*) FROM tiles WHERE job=?1 GROUP BY frame ORDER BY frame", -1,
                         &st, nullptr) == SQLITE_OK) {
    sqlite3_bind_text(st, 1, id.c_str(), int(id.size()), SQLITE_TRANSIENT);
    while (sqlite3_step(st) == SQLITE_ROW) {
      const int n = sqlite3_column_int(st, 1);
      s->tiles_done += n;
      if (n == s->tiles_per_frame) s->frames_done.push_back(sqlite3_column_int(st, 0));
    }
    sqlite3_finalize(st);
  }
  if (sqlite3_prepare_v2(read_db_, "SELECT frame FROM acked_frames WHERE job=?1 ORDER BY frame", -1, &st, nullptr) ==
      SQLITE_OK) {
    sqlite3_bind_text(st, 1, id.c_str(), int(id.size()), SQLITE_TRANSIENT);
    while (sqlite3_step(st) == SQLITE_ROW) s->frames_acknowledged.push_back(sqlite3_column_int(st, 0));
    sqlite3_finalize(st);
  }
  if (sqlite3_prepare_v2(read_db_, "SELECT worker FROM blocklist WHERE job=?1 ORDER BY worker", -1, &st, nullptr) ==
      SQLITE_OK) {
    sqlite3_bind_text(st, 1, id.c_str(), int(id.size()), SQLITE_TRANSIENT);
    while (sqlite3_step(st) == SQLITE_ROW) s->blocklisted.push_back(text(st, 0));
    sqlite3_finalize(st);
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Writes

void JobStore::push(Op op) {
  {
    std::lock_guard lock(mu_);
    queue_.push_back(std::move(op));
  }
  cv_.notify_one();
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
  return s;
}

void JobStore::set_batch_observer(BatchObserver observer) {
  std::lock_guard lock(mu_);
  batch_observer_ = std::move(observer);
}

void JobStore::writer_loop() {
  std::vector<Op> pending;
  BatchObserver observer;
  while (true) {
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty() || !pending.empty(); });
      if (pending.empty() && queue_.empty() && stopping_) break;
      // Everything queued so far is one batch: under load batches grow and commits stay few.
      for (auto& op : queue_) pending.push_back(std::move(op));
      queue_.clear();
      if (!observer) observer = batch_observer_;
    }
    std::string error;
    std::vector<Op> deferred;
    try {
      const auto start = std::chrono::steady_clock::now();
      apply(pending);
      if (observer) {
        uint64_t bytes = 0;
        for (const Op& op : pending) {
          if (const auto* t = std::get_if<TileDone>(&op); t && t->payload) bytes += t->payload->size();
        }
        observer(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), bytes);
      }
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
    for (auto it = pending.begin(); it != pending.end();) {
      if (auto* b = std::get_if<Barrier>(&*it)) {
        b->done->set_value(error);
        it = pending.erase(it);
      } else {
        ++it;
      }
    }
    if (error.empty() && reserve_wanted_) make_reserve();  // writer thread: no lock needed
    if (error.empty()) {
      std::lock_guard lock(mu_);
      if (!healthy_) {
        spdlog::info("storage recovered: {} writes committed", pending.size());
        reserve_wanted_ = true;
      }
      healthy_ = true;
      ++stats_.batches;
      stats_.ops += int64_t(pending.size());
      pending.clear();
      continue;
    }
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

std::vector<JobStore::Op> JobStore::apply(std::vector<Op>& batch, bool new_segment) {
  // 0. Tiles of frames acknowledged (or jobs evicted) in this same batch need no pixels on disk:
  // the client has them. Their rows are written with no location (segment 0), and only the
  // rows: this is what lets acknowledgements through when the disk is full.
  std::set<FrameKey> delivered;
  std::set<JobId> evicted;
  for (const Op& op : batch) {
    if (const auto* a = std::get_if<FrameAck>(&op)) delivered.insert({a->job, a->frame});
    if (const auto* v = std::get_if<Evicted>(&op)) evicted.insert(v->job);
  }
  auto needs_pixels = [&](const TileDone& t) {
    return !delivered.count({t.key.job, t.key.frame}) && !evicted.count(t.key.job);
  };
  std::vector<Op> deferred;
  std::vector<bool> skip(batch.size(), false);
  // 1. One segment with every tile of the batch that needs one, durable before any row that
  // says "done".
  std::vector<const std::string*> payloads;
  for (size_t i = 0; i < batch.size(); ++i) {
    const auto* t = std::get_if<TileDone>(&batch[i]);
    if (!t || !needs_pixels(*t)) continue;
    if (new_segment) {
      payloads.push_back(t->payload.get());
    } else {
      skip[i] = true;
    }
  }
  std::vector<TileStore::Location> at;
  if (!payloads.empty()) at = tiles_->write_segment(payloads);
  size_t next_at = 0;
  const TileStore::Location nowhere{};  // segment 0: never a file (numbers start at 1)
  // A lease issued and ended within one batch never needs a row.
  std::unordered_set<LeaseId> issued, transient;
  LeaseId hwm = lease_hwm_;
  for (const Op& op : batch) {
    if (const auto* l = std::get_if<LeaseIssued>(&op)) {
      issued.insert(l->id);
      hwm = std::max(hwm, l->id);
    } else if (const auto* e = std::get_if<LeaseEnded>(&op)) {
      if (issued.count(e->id)) transient.insert(e->id);
    }
  }
  // 2. One transaction, in queue order.
  auto step = [&](sqlite3_stmt* st) {
    const int rc = sqlite3_step(st);
    sqlite3_reset(st);
    sqlite3_clear_bindings(st);
    if (rc != SQLITE_DONE) throw std::runtime_error(db_path_.string() + ": " + sqlite3_errmsg(db_));
  };
  auto bind_text = [](sqlite3_stmt* st, int i, const std::string& s) {
    sqlite3_bind_text(st, i, s.data(), int(s.size()), SQLITE_TRANSIENT);
  };
  exec("BEGIN IMMEDIATE");
  try {
    for (size_t i = 0; i < batch.size(); ++i) {
      const Op& op = batch[i];
      if (skip[i]) continue;
      if (const auto* j = std::get_if<JobRow>(&op)) {
        const JobSnapshot& s = j->s;
        sqlite3_stmt* st = j->insert ? ins_job_ : upd_job_;
        bind_text(st, 1, s.id);
        if (j->insert) {
          sqlite3_bind_int64(st, 2, int64_t(s.seq));
          bind_text(st, 3, s.spec.name);
          bind_text(st, 4, s.spec.bundle_sha256);
          sqlite3_bind_blob(st, 5, s.spec.overrides.data(), int(s.spec.overrides.size()), SQLITE_TRANSIENT);
          sqlite3_bind_int(st, 6, s.spec.first_frame);
          sqlite3_bind_int(st, 7, s.spec.last_frame);
          sqlite3_bind_int(st, 8, s.spec.width);
          sqlite3_bind_int(st, 9, s.spec.height);
          sqlite3_bind_int(st, 10, s.spec.spp);
          sqlite3_bind_int(st, 11, s.spec.tile_size);
          sqlite3_bind_int(st, 12, s.spec.priority);
          bind_text(st, 13, job_state_name(s.state));
          bind_text(st, 14, s.error);
          sqlite3_bind_double(st, 15, to_unix_seconds(s.submitted));
          if (s.ended) sqlite3_bind_double(st, 16, to_unix_seconds(*s.ended));
          sqlite3_bind_int64(st, 17, s.duplicates_discarded);
          sqlite3_bind_int64(st, 18, int64_t(s.rays));
          bind_text(st, 19, s.spec.owner);
        } else {
          bind_text(st, 2, job_state_name(s.state));
          bind_text(st, 3, s.error);
          if (s.ended) sqlite3_bind_double(st, 4, to_unix_seconds(*s.ended));
          sqlite3_bind_int64(st, 5, s.duplicates_discarded);
          sqlite3_bind_int64(st, 6, int64_t(s.rays));
          sqlite3_bind_int(st, 7, s.spec.priority);
        }
        step(st);
      } else if (const auto* t = std::get_if<TileDone>(&op)) {
        bind_text(ins_tile_, 1, t->key.job);
        sqlite3_bind_int(ins_tile_, 2, t->key.frame);
        sqlite3_bind_int(ins_tile_, 3, t->key.tile);
        sqlite3_bind_int64(ins_tile_, 4, int64_t(t->rays));
        sqlite3_bind_double(ins_tile_, 5, t->seconds);
        const TileStore::Location& loc = needs_pixels(*t) ? at[next_at++] : nowhere;
        sqlite3_bind_int64(ins_tile_, 6, loc.segment);
        sqlite3_bind_int64(ins_tile_, 7, loc.offset);
        sqlite3_bind_int64(ins_tile_, 8, loc.length);
        step(ins_tile_);
      } else if (const auto* a = std::get_if<FrameAck>(&op)) {
        bind_text(ins_ack_, 1, a->job);
        sqlite3_bind_int(ins_ack_, 2, a->frame);
        step(ins_ack_);
      } else if (const auto* l = std::get_if<LeaseIssued>(&op)) {
        if (transient.count(l->id)) continue;
        sqlite3_bind_int64(ins_lease_, 1, int64_t(l->id));
        bind_text(ins_lease_, 2, l->worker);
        bind_text(ins_lease_, 3, l->tile.job);
        sqlite3_bind_int(ins_lease_, 4, l->tile.frame);
        sqlite3_bind_int(ins_lease_, 5, l->tile.tile);
        sqlite3_bind_double(ins_lease_, 6, l->issued);
        step(ins_lease_);
      } else if (const auto* e = std::get_if<LeaseEnded>(&op)) {
        if (transient.count(e->id)) continue;
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
    if (hwm != lease_hwm_) {
      sqlite3_bind_int64(set_hwm_, 1, int64_t(hwm));
      step(set_hwm_);
    }
    exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    // No row points into this batch's segment; the retry writes a new one. (Were this unlink
    // lost in a crash, the next start would delete the segment as an orphan.)
    if (!at.empty()) tiles_->remove_segment(at.front().segment);
    throw;
  }
  lease_hwm_ = hwm;
  // 3. Only now may pixels go: the rows that say the client has them are committed. Bookkeeping
  // in queue order; a segment is deleted once no tile of an unacknowledged frame is left in it.
  std::vector<int64_t> emptied;
  next_at = 0;
  for (size_t i = 0; i < batch.size(); ++i) {
    const Op& op = batch[i];
    if (skip[i]) {
      deferred.push_back(op);
    } else if (const auto* t = std::get_if<TileDone>(&op)) {
      if (needs_pixels(*t)) track_tile(t->key, at[next_at++].segment);
    } else if (const auto* a = std::get_if<FrameAck>(&op)) {
      release_frame({a->job, a->frame}, emptied);
    } else if (const auto* v = std::get_if<Evicted>(&op)) {
      release_job(v->job, emptied);
    }
  }
  for (int64_t seg : emptied) {
    // A segment can empty and then gain a later tile of the same batch: check at the end.
    auto it = segment_live_.find(seg);
    if (it != segment_live_.end() && it->second == 0) {
      segment_live_.erase(it);
      tiles_->remove_segment(seg);
    }
  }
  return deferred;
}

void JobStore::make_reserve() {
  // A few hundred KiB held back on the data disk. When the disk fills up completely, SQLite can
  // no longer checkpoint its WAL (the database file must grow a little), so the WAL can no
  // longer be cut back, and nothing could ever be written again, acknowledgements included,
  // even with nothing left to delete. Giving the reserve back breaks that deadlock.
  reserve_wanted_ = false;
  const fs::path reserve = dir_ / ".reserve";
  std::error_code ec;
  if (fs::exists(reserve, ec)) return;
  const int fd = ::open(reserve.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return;
  const bool ok = ::posix_fallocate(fd, 0, kReserveBytes) == 0 && ::fsync(fd) == 0;
  ::close(fd);
  if (!ok) {
    ::unlink(reserve.c_str());
    reserve_wanted_ = true;  // try again after the next successful batch
    spdlog::warn("cannot set aside {} KiB on the data disk (full?): will try again", kReserveBytes / 1024);
  }
}

void JobStore::release_reserve() {
  const fs::path reserve = dir_ / ".reserve";
  if (::unlink(reserve.c_str()) == 0) {
    spdlog::warn("disk full: gave back the {} KiB reserve so that the database can checkpoint", kReserveBytes / 1024);
  }
  // Copy the WAL into the database and cut it to nothing: the space the WAL held comes back.
  sqlite3_exec(db_, "PRAGMA wal_checkpoint(TRUNCATE)", nullptr, nullptr, nullptr);
}

void JobStore::reclaim_delivered(const std::vector<Op>& pending) {
  // The segments that the queued acknowledgements (and evictions) will delete once committed,
  // deleted now, because on a full disk the commit cannot happen until something is deleted.
  // The bookkeeping is left alone: it is updated when the commit goes through (deleting again
  // is harmless). The price: should the coordinator die before that commit, those frames are
  // not acknowledged in the database and their rows point nowhere, so they are rendered again
  // (never served wrong); without this, a full disk never recovers while running.
  std::unordered_map<int64_t, int64_t> live = segment_live_;
  std::vector<int64_t> emptied;
  auto release = [&](const FrameKey& f) {
    auto it = frame_tiles_.find(f);
    if (it == frame_tiles_.end()) return;
    for (const auto& [tile, seg] : it->second) {
      if (--live[seg] == 0) emptied.push_back(seg);
    }
  };
  std::set<FrameKey> seen;
  for (const Op& op : pending) {
    if (const auto* a = std::get_if<FrameAck>(&op)) {
      if (seen.insert({a->job, a->frame}).second) release({a->job, a->frame});
    } else if (const auto* v = std::get_if<Evicted>(&op)) {
      for (auto it = frame_tiles_.lower_bound({v->job, std::numeric_limits<int>::min()});
           it != frame_tiles_.end() && it->first.first == v->job; ++it) {
        if (seen.insert(it->first).second) release(it->first);
      }
    }
  }
  if (emptied.empty()) return;
  for (int64_t seg : emptied) tiles_->remove_segment(seg);
  spdlog::warn("disk full: deleted {} tile segments holding only frames a client already has (their "
               "acknowledgements are not committed yet) to make room",
               emptied.size());
}

void JobStore::track_tile(const TileKey& key, int64_t segment) {
  auto& tiles = frame_tiles_[{key.job, key.frame}];
  auto [it, inserted] = tiles.try_emplace(key.tile, segment);
  if (!inserted) {
    // The same tile stored again (INSERT OR REPLACE): its old record is dead.
    --segment_live_[it->second];
    it->second = segment;
  }
  ++segment_live_[segment];
}

void JobStore::release_frame(const FrameKey& frame, std::vector<int64_t>& emptied) {
  auto it = frame_tiles_.find(frame);
  if (it == frame_tiles_.end()) return;
  for (const auto& [tile, seg] : it->second) {
    if (--segment_live_[seg] == 0) emptied.push_back(seg);
  }
  frame_tiles_.erase(it);
}

void JobStore::release_job(const JobId& job, std::vector<int64_t>& emptied) {
  auto it = frame_tiles_.lower_bound({job, std::numeric_limits<int>::min()});
  while (it != frame_tiles_.end() && it->first.first == job) {
    const FrameKey key = (it++)->first;
    release_frame(key, emptied);
  }
}

}  // namespace tessera::server

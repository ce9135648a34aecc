// SPDX-License-Identifier: Apache-2.0
// Reading the store back at start: the lease marks, the resident jobs with their done tiles
// (each stored record checked), the clean-up of what the last run left behind (rows of unusable
// tiles, leases in flight, orphan segments), and the refusal to start on a lost database.
#include <spdlog/spdlog.h>

#include "job_row.h"
#include "job_store.h"
#include "sqlite_util.h"

namespace tessera::server {

namespace fs = std::filesystem;

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

void JobStore::query(const std::string& sql, const std::function<void(sqlite3_stmt*)>& row) {
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
    throw StoreError(db_path_.string() + ": " + sqlite3_errmsg(db_));
  }
  int rc;
  while ((rc = sqlite3_step(st)) == SQLITE_ROW) row(st);
  sqlite3_finalize(st);
  if (rc != SQLITE_DONE) throw StoreError(db_path_.string() + ": " + sqlite3_errmsg(db_));
}

JobStore::Loaded JobStore::load(const TileCheck& check) {
  Loaded out;
  load_lease_marks(out);
  segments_.clear();
  query(std::string("SELECT ") + kJobColumns + " FROM jobs WHERE resident=1 ORDER BY seq", [&](sqlite3_stmt* st) {
    JobRecord r;
    r.header() = read_job_row(st).header();
    out.jobs.push_back(std::move(r));
  });
  std::vector<TileKey> missing;
  for (JobRecord& r : out.jobs) {
    std::set<int> acked;
    query("SELECT frame FROM acked_frames WHERE job='" + r.id + "'", [&](sqlite3_stmt* st) {
      acked.insert(sqlite3_column_int(st, 0));
    });
    r.acknowledged.assign(acked.begin(), acked.end());
    query("SELECT worker FROM blocklist WHERE job='" + r.id + "' ORDER BY worker",
          [&](sqlite3_stmt* st) { r.blocklisted.push_back(column_text(st, 0)); });
    load_done_tiles(r, acked, check, missing, out);
  }
  drop_stale_rows(missing);
  out.orphans_removed = remove_orphans();
  // Last: once one is queued, the writer works on the connection this function used.
  for (const JobId& job : unshed_jobs()) queue_shedding(job);
  return out;
}

void JobStore::load_lease_marks(Loaded& out) {
  LeaseId hwm = 0;
  query("SELECT value FROM meta WHERE key='lease_hwm'", [&](sqlite3_stmt* st) { hwm = LeaseId(sqlite3_column_int64(st, 0)); });
  query("SELECT count(*), coalesce(max(id), 0) FROM leases", [&](sqlite3_stmt* st) {
    out.leases_requeued = sqlite3_column_int64(st, 0);
    hwm = std::max(hwm, LeaseId(sqlite3_column_int64(st, 1)));
  });
  out.next_lease = hwm + 1;
  lease_hwm_ = hwm;
}

void JobStore::load_done_tiles(JobRecord& r, const std::set<int>& acked, const TileCheck& check,
                               std::vector<TileKey>& missing, Loaded& out) {
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
              missing.push_back({r.id, t.frame, t.tile});
              ++out.tiles_missing;
              return;
            }
            t.output.payload = std::make_shared<const std::string>(std::move(*got.bytes));
            segments_.track({r.id, t.frame, t.tile}, at.segment);
          }
          r.done.push_back(std::move(t));
        });
}

void JobStore::drop_stale_rows(const std::vector<TileKey>& missing) {
  // Dropping the rows of unusable tiles and the leases of the last run: on a full disk these
  // deletions may fail (SQLite needs room to delete); that must not stop the coordinator, and
  // they are repeated at the next start. (Lease rows left behind are only ever read here.)
  try {
    exec("BEGIN");
    for (const TileKey& k : missing) {
      exec(("DELETE FROM tiles WHERE job='" + k.job + "' AND frame=" + std::to_string(k.frame) +
            " AND tile=" + std::to_string(k.tile))
               .c_str());
    }
    // Leases in flight at the last stop: their tiles are queued again (rows without a done tile).
    exec("DELETE FROM leases");
    exec("COMMIT");
  } catch (const std::exception& e) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    spdlog::warn("cannot clean up the database at start ({}): carrying on; retried at the next start", e.what());
  }
}

int64_t JobStore::remove_orphans() {
  // Orphans: everything in tiles/ but the segments holding a readable tile of an unacknowledged
  // frame of a resident job. That is segments of a crash between the segment's sync and the
  // commit, of acknowledged frames or evicted jobs whose unlink was interrupted, and any
  // directory left by schema version 1.
  std::error_code ec;
  std::vector<fs::path> doomed;
  for (const auto& e : fs::directory_iterator(tiles_->root(), ec)) {
    const auto n = TileStore::parse_segment_name(e.path().filename().string());
    if (!n || !segments_.counts(*n)) doomed.push_back(e.path());
  }
  int64_t removed_files = 0;
  for (const fs::path& p : doomed) {
    std::error_code rec;
    const auto removed = fs::remove_all(p, rec);
    if (removed != static_cast<std::uintmax_t>(-1)) removed_files += int64_t(removed);
  }
  return removed_files;
}

}  // namespace tessera::server

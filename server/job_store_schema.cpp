// SPDX-License-Identifier: Apache-2.0
#include "job_store_schema.h"

#include <spdlog/spdlog.h>

#include <stdexcept>
#include <vector>

#include "sqlite_util.h"

namespace tessera::server {

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
  resident INTEGER NOT NULL DEFAULT 1, owner TEXT NOT NULL DEFAULT '', output BLOB NOT NULL DEFAULT x'');
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

// Version 4: what an evicted job did, once its tile and acknowledged-frame rows are shed
// (job_summary.h); frames as ranges, "0-9,12". A job without a row here still has its rows.
const char* kSummariesTable =
    "CREATE TABLE job_summaries(job TEXT PRIMARY KEY, tiles_done INTEGER NOT NULL, frames_done TEXT NOT NULL, "
    "frames_acknowledged TEXT NOT NULL) WITHOUT ROWID";

// The single integer the query answers, or `otherwise` when it answers no row.
int query_int(sqlite3* db, const char* sql, int otherwise) {
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, sql, -1, &st, nullptr);
  int value = otherwise;
  if (sqlite3_step(st) == SQLITE_ROW) value = sqlite3_column_int(st, 0);
  sqlite3_finalize(st);
  return value;
}

void create_schema(sqlite3* db, const std::string& name) {
  exec_sql(db, name, "BEGIN");
  exec_sql(db, name, kSchema);
  exec_sql(db, name, kSummariesTable);
  exec_sql(db, name, ("INSERT INTO schema_version VALUES (" + std::to_string(kStoreSchemaVersion) + ")").c_str());
  exec_sql(db, name, "COMMIT");
}

void migrate_from_version_2(sqlite3* db, const std::string& name) {
  // Version 3 added jobs.owner (the per-client job quota survives a restart) and the blocklist
  // table (so do blocklists). Jobs stored by version 2 have no owner: they count for no client,
  // as before; and no blocklist.
  exec_sql(db, name, "BEGIN");
  exec_sql(db, name, "ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT ''");
  exec_sql(db, name,
           "CREATE TABLE blocklist(job TEXT NOT NULL, worker TEXT NOT NULL, PRIMARY KEY(job, worker)) WITHOUT ROWID");
  exec_sql(db, name, "UPDATE schema_version SET version=3");
  exec_sql(db, name, "COMMIT");
  spdlog::info("database {}: migrated schema version 2 to 3", name);
}

void migrate_from_version_3(sqlite3* db, const std::string& name) {
  // Version 4 added job_summaries. The evicted jobs of version 3 keep every row: the job store
  // sheds them after it starts (JobStore::load), as it does a job evicted now.
  exec_sql(db, name, "BEGIN");
  exec_sql(db, name, kSummariesTable);
  exec_sql(db, name, "UPDATE schema_version SET version=4");
  exec_sql(db, name, "COMMIT");
  spdlog::info("database {}: migrated schema version 3 to 4", name);
}

void migrate_from_version_4(sqlite3* db, const std::string& name) {
  // Version 5 added jobs.output (a job's recorded output, a serialized JobOutput). Jobs stored
  // by version 4 have none: a client attaching names where their frames go, as before.
  exec_sql(db, name, "BEGIN");
  exec_sql(db, name, "ALTER TABLE jobs ADD COLUMN output BLOB NOT NULL DEFAULT x''");
  exec_sql(db, name, "UPDATE schema_version SET version=5");
  exec_sql(db, name, "COMMIT");
  spdlog::info("database {}: migrated schema version 4 to 5", name);
}

}  // namespace

void check_database_integrity(sqlite3* db, const std::string& name) {
  sqlite3_stmt* st = nullptr;
  int rc = sqlite3_prepare_v2(db, "PRAGMA quick_check", -1, &st, nullptr);
  std::vector<std::string> problems;
  if (rc == SQLITE_OK) {
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
      const std::string row = column_text(st, 0);
      if (row != "ok" && problems.size() < 5) problems.push_back(row);
    }
  }
  const std::string msg = sqlite3_errmsg(db);
  const int code = sqlite3_extended_errcode(db) & 0xff;
  sqlite3_finalize(st);
  // The file could not be read at all (disk full, I/O error, permissions): say so, rather
  // than call a good database corrupt.
  if (rc != SQLITE_DONE && code != SQLITE_NOTADB && code != SQLITE_CORRUPT) {
    throw std::runtime_error("cannot read the database " + name + " (" + msg +
                             "): check the disk holding it (full, read-only, failing?)");
  }
  if (rc != SQLITE_DONE) {
    throw std::runtime_error("the database " + name + " is unreadable (" + msg +
                             "): it is corrupt or not a Tessera database. Move it away (the coordinator then "
                             "starts with no jobs) or restore a backup");
  }
  if (!problems.empty()) {
    std::string all;
    for (const auto& p : problems) all += (all.empty() ? "" : "; ") + p;
    throw std::runtime_error("the database " + name + " failed its integrity check: " + all +
                             ". Move it away (the coordinator then starts with no jobs) or restore a backup");
  }
}

void set_journal_mode(sqlite3* db, const std::string& name) {
  exec_sql(db, name, "PRAGMA journal_mode=WAL");
  // FULL: a commit is on disk when it returns (one fsync of the WAL per batch).
  exec_sql(db, name, "PRAGMA synchronous=FULL");
  // A bounded WAL: checkpoint every 256 pages (1 MiB) and cut the file back to 1 MiB after a
  // checkpoint. SQLite's default (1000 pages, never cut back) let the WAL alone grow to fill
  // a small data disk.
  exec_sql(db, name, "PRAGMA wal_autocheckpoint=256");
  exec_sql(db, name, "PRAGMA journal_size_limit=1048576");
}

void create_or_migrate_schema(sqlite3* db, const std::string& name) {
  if (query_int(db, "SELECT count(*) FROM sqlite_master WHERE type='table' AND name='schema_version'", 0) == 0) {
    if (query_int(db, "SELECT count(*) FROM sqlite_master", 0) > 0) {
      throw std::runtime_error("the database " + name + " is an SQLite database but not a Tessera one (no "
                               "schema_version table): use another --data-dir");
    }
    create_schema(db, name);
    return;
  }
  int version = query_int(db, "SELECT version FROM schema_version", -1);
  if (version == 1) {
    throw std::runtime_error("the database " + name + " has schema version 1 (a file per tile under tiles/<job>/); "
                             "this tessera-server reads version " + std::to_string(kStoreSchemaVersion) +
                             " (tiles in segment files) and does not migrate it. Let the old tessera-server "
                             "finish its jobs, or start with another --data-dir");
  }
  if (version == 2) {
    migrate_from_version_2(db, name);
    version = 3;
  }
  if (version == 3) {
    migrate_from_version_3(db, name);
    version = 4;
  }
  if (version == 4) {
    migrate_from_version_4(db, name);
    version = 5;
  }
  if (version != kStoreSchemaVersion) {
    throw std::runtime_error("the database " + name + " has schema version " + std::to_string(version) +
                             "; this tessera-server reads version " + std::to_string(kStoreSchemaVersion) +
                             ". Use the tessera-server that wrote it, or another --data-dir");
  }
}

}  // namespace tessera::server

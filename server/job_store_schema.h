// SPDX-License-Identifier: Apache-2.0
// The job store's database: its tables (the on-disk format, together with tile_store.h's
// segment records), the schema version this release reads, and what is checked and set each
// time it is opened. A change to the tables needs a new version and a migration from the last.
#pragma once

#include <sqlite3.h>

#include <string>

namespace tessera::server {

// 1: a file per tile (refused with a message, not migrated: no farm ran it in production).
// 2: tiles in segment files (tiles.segment/offset/length).
// 3: jobs.owner and the blocklist table.
// 4: the job_summaries table: evicted jobs shed their tile and frame rows (versions 2 and 3 are
//    migrated).
constexpr int kStoreSchemaVersion = 5;

// PRAGMA quick_check: a file that is not a database, or a damaged one, stops the coordinator at
// start with the file's name, instead of losing jobs later. Throws std::runtime_error naming
// `name` (and telling a disk that cannot be read from a corrupt database).
void check_database_integrity(sqlite3* db, const std::string& name);
// WAL, synchronous=FULL and a bounded WAL. Throws std::runtime_error.
void set_journal_mode(sqlite3* db, const std::string& name);
// Creates the tables in an empty database and migrates versions 2 and 3; refuses version 1, versions
// this release does not know and SQLite databases that are not Tessera's. Throws
// std::runtime_error naming `name`.
void create_or_migrate_schema(sqlite3* db, const std::string& name);

}  // namespace tessera::server

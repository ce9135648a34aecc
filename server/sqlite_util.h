// SPDX-License-Identifier: Apache-2.0
// Small SQLite helpers shared by the job store's files: columns as strings, text bound by copy,
// and statements run with their error thrown, naming the database.
#pragma once

#include <sqlite3.h>

#include <stdexcept>
#include <string>

namespace tessera::server {

inline std::string column_text(sqlite3_stmt* st, int col) {
  const auto* p = sqlite3_column_text(st, col);
  return p ? std::string(reinterpret_cast<const char*>(p), size_t(sqlite3_column_bytes(st, col))) : std::string();
}

inline std::string column_blob(sqlite3_stmt* st, int col) {
  const void* p = sqlite3_column_blob(st, col);
  return p ? std::string(static_cast<const char*>(p), size_t(sqlite3_column_bytes(st, col))) : std::string();
}

inline void bind_text(sqlite3_stmt* st, int i, const std::string& s) {
  sqlite3_bind_text(st, i, s.data(), int(s.size()), SQLITE_TRANSIENT);
}

// Runs `sql` (one or more statements); throws std::runtime_error "<name>: <SQLite's message>".
inline void exec_sql(sqlite3* db, const std::string& name, const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : sqlite3_errmsg(db);
    sqlite3_free(err);
    throw std::runtime_error(name + ": " + msg);
  }
}

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "job_summary.h"

#include <stdexcept>

#include "sqlite_util.h"

namespace tessera::server {

namespace {

// Runs `sql` (parameter 1: the job), calling `row` for each row; throws naming `db_name`.
template <class Row>
void each_row(sqlite3* db, const std::string& db_name, const char* sql, const std::string& job, Row&& row) {
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) != SQLITE_OK) {
    throw std::runtime_error(db_name + ": " + sqlite3_errmsg(db));
  }
  bind_text(st, 1, job);
  int rc;
  while ((rc = sqlite3_step(st)) == SQLITE_ROW) row(st);
  sqlite3_finalize(st);
  if (rc != SQLITE_DONE) throw std::runtime_error(db_name + ": " + sqlite3_errmsg(db));
}

}  // namespace

JobSummary count_job_summary(sqlite3* db, const std::string& db_name, const std::string& job, int tiles_per_frame) {
  JobSummary s;
  each_row(db, db_name, "SELECT frame, count(*) FROM tiles WHERE job=?1 GROUP BY frame ORDER BY frame", job,
           [&](sqlite3_stmt* st) {
             const int n = sqlite3_column_int(st, 1);
             s.tiles_done += n;
             if (n == tiles_per_frame) s.frames_done.push_back(sqlite3_column_int(st, 0));
           });
  each_row(db, db_name, "SELECT frame FROM acked_frames WHERE job=?1 ORDER BY frame", job,
           [&](sqlite3_stmt* st) { s.frames_acknowledged.push_back(sqlite3_column_int(st, 0)); });
  return s;
}

std::optional<JobSummary> read_job_summary(sqlite3* db, const std::string& db_name, const std::string& job) {
  std::optional<JobSummary> s;
  each_row(db, db_name, "SELECT tiles_done, frames_done, frames_acknowledged FROM job_summaries WHERE job=?1", job,
           [&](sqlite3_stmt* st) {
             s = JobSummary{sqlite3_column_int64(st, 0), frames_from_ranges(column_text(st, 1)),
                            frames_from_ranges(column_text(st, 2))};
           });
  return s;
}

void write_job_summary(sqlite3* db, const std::string& db_name, const std::string& job, const JobSummary& s) {
  sqlite3_stmt* st = nullptr;
  if (sqlite3_prepare_v2(db,
                         "INSERT OR REPLACE INTO job_summaries(job, tiles_done, frames_done, frames_acknowledged) "
                         "VALUES(?1,?2,?3,?4)",
                         -1, &st, nullptr) != SQLITE_OK) {
    throw std::runtime_error(db_name + ": " + sqlite3_errmsg(db));
  }
  bind_text(st, 1, job);
  sqlite3_bind_int64(st, 2, s.tiles_done);
  bind_text(st, 3, frames_to_ranges(s.frames_done));
  bind_text(st, 4, frames_to_ranges(s.frames_acknowledged));
  const int rc = sqlite3_step(st);
  sqlite3_finalize(st);
  if (rc != SQLITE_DONE) throw std::runtime_error(db_name + ": " + sqlite3_errmsg(db));
}

std::string frames_to_ranges(const std::vector<int>& frames) {
  std::string out;
  for (size_t i = 0; i < frames.size();) {
    size_t j = i;
    while (j + 1 < frames.size() && frames[j + 1] == frames[j] + 1) ++j;
    if (!out.empty()) out += ',';
    out += std::to_string(frames[i]);
    if (j > i) out += '-' + std::to_string(frames[j]);
    i = j + 1;
  }
  return out;
}

std::vector<int> frames_from_ranges(const std::string& text) {
  std::vector<int> frames;
  size_t at = 0;
  while (at < text.size()) {
    size_t end = text.find(',', at);
    if (end == std::string::npos) end = text.size();
    const std::string range = text.substr(at, end - at);
    const size_t dash = range.find('-', 1);  // not a leading minus sign
    try {
      const int lo = std::stoi(range.substr(0, dash));
      const int hi = dash == std::string::npos ? lo : std::stoi(range.substr(dash + 1));
      if (hi < lo) throw std::invalid_argument(range);
      for (int f = lo; f <= hi; ++f) frames.push_back(f);
    } catch (const std::logic_error&) {
      throw std::runtime_error("malformed frame ranges '" + text + "' in a job summary");
    }
    at = end + 1;
  }
  return frames;
}

}  // namespace tessera::server

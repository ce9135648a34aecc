// SPDX-License-Identifier: Apache-2.0
// Shedding the rows of evicted jobs: once a job has left memory, its tile rows (one per finished
// tile), acknowledged-frame rows and lease rows are deleted by the writer, a chunk per
// transaction, after the batches it commits and while it has nothing else to write. The job's own
// row stays, and a summary of what it did is written in the same transaction as the first rows
// deleted (job_summary.h): `tessera status JOB` answers the same before, during and after, and a
// crash between two chunks leaves a job whose summary is whole and whose last rows are shed at
// the next start. Restore never reads an evicted job's rows (it loads resident jobs only).
#include <spdlog/spdlog.h>

#include "job_row.h"
#include "job_store.h"
#include "job_summary.h"
#include "sqlite_util.h"

namespace tessera::server {

void JobStore::queue_shedding(const JobId& job) {
  {
    std::lock_guard lock(mu_);
    to_shed_.push_back(job);
  }
  cv_.notify_one();  // an idle writer sheds it now
}

std::vector<JobId> JobStore::unshed_jobs() {
  std::vector<JobId> jobs;
  query("SELECT id FROM jobs WHERE resident=0 AND (EXISTS(SELECT 1 FROM tiles WHERE job=jobs.id) OR "
        "EXISTS(SELECT 1 FROM acked_frames WHERE job=jobs.id)) ORDER BY seq",
        [&](sqlite3_stmt* st) { jobs.push_back(column_text(st, 0)); });
  return jobs;
}

void JobStore::shed_chunk() {
  JobId job;
  {
    std::lock_guard lock(mu_);
    if (to_shed_.empty() || shed_failing_) return;
    job = to_shed_.front();
  }
  bool done = false;
  try {
    exec("BEGIN IMMEDIATE");
    done = shed_rows_of(job);
    exec("COMMIT");
  } catch (const std::exception& e) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    // A full disk (SQLite needs room to delete): tried again once a batch commits.
    shed_failing_ = true;
    spdlog::warn("storage: cannot shed the rows of evicted job {} now ({}): tried again later", job, e.what());
    return;
  }
  if (!done) return;
  std::lock_guard lock(mu_);
  to_shed_.pop_front();
}

bool JobStore::shed_rows_of(const JobId& job) {
  const std::string name = db_path_.string();
  std::optional<JobSnapshot> row;
  int first = 0;
  query("SELECT " + std::string(kJobColumns) + " FROM jobs WHERE id='" + job + "'",
        [&](sqlite3_stmt* st) { row = read_job_row(st); });
  const int tiles_per_frame = row ? std::max(1, row->tiles_per_frame) : 1;
  if (!read_job_summary(db_, name, job)) {
    write_job_summary(db_, name, job, count_job_summary(db_, name, job, tiles_per_frame));
    // Segment numbers only grow, also once the rows that held the highest are gone.
    exec(("INSERT INTO meta(key, value) SELECT 'segment_hwm', coalesce(max(segment), 0) FROM tiles WHERE job='" +
          job + "' ON CONFLICT(key) DO UPDATE SET value=max(value, excluded.value)")
             .c_str());
  }
  bool left = false;
  query("SELECT min(frame) FROM tiles WHERE job='" + job + "'", [&](sqlite3_stmt* st) {
    left = sqlite3_column_type(st, 0) != SQLITE_NULL;
    first = sqlite3_column_int(st, 0);
  });
  if (left) {
    // Whole frames, about kShedChunkRows rows (a frame with more tiles goes alone).
    const int frames = std::max(1, kShedChunkRows / tiles_per_frame);
    exec(("DELETE FROM tiles WHERE job='" + job + "' AND frame>=" + std::to_string(first) +
          " AND frame<" + std::to_string(int64_t(first) + frames))
             .c_str());
    query("SELECT EXISTS(SELECT 1 FROM tiles WHERE job='" + job + "')",
          [&](sqlite3_stmt* st) { left = sqlite3_column_int(st, 0) != 0; });
    if (left) return false;
  }
  exec(("DELETE FROM acked_frames WHERE job='" + job + "'").c_str());
  exec(("DELETE FROM leases WHERE job='" + job + "'").c_str());
  return true;
}

int64_t JobStore::segment_high_water() {
  int64_t hwm = 0;
  query("SELECT max(coalesce((SELECT max(segment) FROM tiles), 0), "
        "coalesce((SELECT value FROM meta WHERE key='segment_hwm'), 0))",
        [&](sqlite3_stmt* st) { hwm = sqlite3_column_int64(st, 0); });
  return hwm;
}

}  // namespace tessera::server

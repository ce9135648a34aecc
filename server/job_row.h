// SPDX-License-Identifier: Apache-2.0
// A row of the jobs table (job_store_schema.cpp) <-> a JobSnapshot: the columns read, in order,
// and the values bound to the job store's insert and update statements. Times are stored as
// Unix seconds; steady-clock time points are converted at the boundary.
#pragma once

#include <sqlite3.h>

#include "scheduler.h"

namespace tessera::server {

// The columns read_job_row() reads, in its order: "SELECT <kJobColumns> FROM jobs ...".
extern const char* const kJobColumns;
// The snapshot of the job in the current row. A state the database names that this release
// does not know reads as failed, with the reason as its error. tiles_per_frame and tiles_total
// are worked out from the spec; the counters of a running job (tiles done, leased) are not
// stored and stay 0.
JobSnapshot read_job_row(sqlite3_stmt* st);

// The statement that stores a new job (every column), and its values.
extern const char* const kInsertJobSql;
void bind_job_insert(sqlite3_stmt* st, const JobSnapshot& s);
// The statement that stores what changes while a job runs (state, error, end, counters, and the
// priority, which a client may change), and its values.
extern const char* const kUpdateJobSql;
void bind_job_update(sqlite3_stmt* st, const JobSnapshot& s);

// Steady-clock time points <-> Unix seconds (what the database stores).
double to_unix_seconds(TimePoint t);
TimePoint from_unix_seconds(double unix_s);

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
#include "job_row.h"

#include <algorithm>
#include <chrono>
#include <optional>

#include "sqlite_util.h"
#include "tile/tile_grid.h"

namespace tessera::server {

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

std::optional<JobState> parse_state(const std::string& s) {
  for (JobState st : {JobState::kQueued, JobState::kRunning, JobState::kDone, JobState::kCancelled, JobState::kFailed}) {
    if (s == job_state_name(st)) return st;
  }
  return std::nullopt;
}

}  // namespace

const char* const kJobColumns =
    "id, seq, name, bundle, overrides, first_frame, last_frame, width, height, spp, tile_size, priority, state, "
    "error, submitted, ended, duplicates, rays, owner, output";

const char* const kInsertJobSql =
    "INSERT OR REPLACE INTO jobs(id, seq, name, bundle, overrides, first_frame, last_frame, width, height, spp, "
    "tile_size, priority, state, error, submitted, ended, duplicates, rays, owner, output) "
    "VALUES(?1,?2,?3,?4,?5,?6,?7,?8,?9,?10,?11,?12,?13,?14,?15,?16,?17,?18,?19,?20)";

const char* const kUpdateJobSql =
    "UPDATE jobs SET state=?2, error=?3, ended=?4, duplicates=?5, rays=?6, priority=?7 WHERE id=?1";

JobSnapshot read_job_row(sqlite3_stmt* st) {
  JobSnapshot s;
  s.id = column_text(st, 0);
  s.seq = uint64_t(sqlite3_column_int64(st, 1));
  s.spec.name = column_text(st, 2);
  s.spec.bundle_sha256 = column_text(st, 3);
  s.spec.overrides = column_blob(st, 4);
  s.spec.first_frame = sqlite3_column_int(st, 5);
  s.spec.last_frame = sqlite3_column_int(st, 6);
  s.spec.width = sqlite3_column_int(st, 7);
  s.spec.height = sqlite3_column_int(st, 8);
  s.spec.spp = sqlite3_column_int(st, 9);
  s.spec.tile_size = std::max(1, sqlite3_column_int(st, 10));
  s.spec.priority = sqlite3_column_int(st, 11);
  const std::string state = column_text(st, 12);
  s.state = parse_state(state).value_or(JobState::kFailed);
  s.error = column_text(st, 13);
  if (!parse_state(state)) s.error = "unknown state '" + state + "' in the database";
  s.submitted = from_unix_seconds(sqlite3_column_double(st, 14));
  if (sqlite3_column_type(st, 15) != SQLITE_NULL) s.ended = from_unix_seconds(sqlite3_column_double(st, 15));
  s.duplicates_discarded = sqlite3_column_int64(st, 16);
  s.rays = uint64_t(sqlite3_column_int64(st, 17));
  s.spec.owner = column_text(st, 18);
  s.spec.output = column_blob(st, 19);
  s.tiles_per_frame = TileGrid(s.spec.width, s.spec.height, s.spec.tile_size).count();
  s.tiles_total = int64_t(s.spec.last_frame - s.spec.first_frame + 1) * s.tiles_per_frame;
  return s;
}

void bind_job_insert(sqlite3_stmt* st, const JobSnapshot& s) {
  bind_text(st, 1, s.id);
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
  sqlite3_bind_blob(st, 20, s.spec.output.data(), int(s.spec.output.size()), SQLITE_TRANSIENT);
}

void bind_job_update(sqlite3_stmt* st, const JobSnapshot& s) {
  bind_text(st, 1, s.id);
  bind_text(st, 2, job_state_name(s.state));
  bind_text(st, 3, s.error);
  if (s.ended) sqlite3_bind_double(st, 4, to_unix_seconds(*s.ended));
  sqlite3_bind_int64(st, 5, s.duplicates_discarded);
  sqlite3_bind_int64(st, 6, int64_t(s.rays));
  sqlite3_bind_int(st, 7, s.spec.priority);
}

}  // namespace tessera::server

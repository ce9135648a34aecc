// SPDX-License-Identifier: Apache-2.0
// What a job did, as `tessera status JOB` shows it once the job has left memory: its tiles done,
// its finished frames and its acknowledged frames. Counted from the job's rows (a tile row per
// finished tile, a row per acknowledged frame) until the job store sheds them, then read from the
// one row that replaces them (table job_summaries, job_store_schema.cpp; frames kept as ranges,
// "0-9,12"). The summary is written in the same transaction as the first rows shed, so a reader
// sees either every row or the summary, never a job half counted.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tessera::server {

struct JobSummary {
  int64_t tiles_done = 0;
  std::vector<int> frames_done;          // every tile of the frame done
  std::vector<int> frames_acknowledged;  // a client wrote the frame
  bool operator==(const JobSummary&) const = default;
};

// Counted from the job's tile and acknowledged-frame rows; a frame is done when it has
// `tiles_per_frame` tile rows. Throws std::runtime_error naming `db_name`.
JobSummary count_job_summary(sqlite3* db, const std::string& db_name, const std::string& job, int tiles_per_frame);
// The stored summary of a job whose rows were shed, or nullopt (not shed yet). Throws likewise.
std::optional<JobSummary> read_job_summary(sqlite3* db, const std::string& db_name, const std::string& job);
// Stores it (in the caller's transaction). Throws likewise.
void write_job_summary(sqlite3* db, const std::string& db_name, const std::string& job, const JobSummary& s);

// Sorted frame numbers <-> ranges ("0-9,12"; "" for none). Throws std::runtime_error on a
// malformed text.
std::string frames_to_ranges(const std::vector<int>& frames);
std::vector<int> frames_from_ranges(const std::string& text);

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// The progress display of `tessera submit` and `tessera watch`: a bar redrawn in place on a
// terminal, a plain line every few seconds otherwise (logs, CI).
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>

namespace tessera::cli {

// One reading of a job's progress as this client sees it.
struct ProgressCounts {
  int64_t total = 0;        // the job's tiles
  int64_t done_before = 0;  // tiles of the frames an earlier client already received
  int64_t received = 0;     // tiles received by this client
  uint64_t rays = 0;        // the rays those tiles traced
  double elapsed = 0;       // seconds since this client started watching
};

// The display's text for `counts`. Tiles done are done_before + received (at most total); the
// rates and the ETA count this client's tiles over its own time, since earlier tiles came at
// another rate. On a terminal a bar that overwrites itself:
//   "\r[###############...............] 50/100 tiles  1.2 Mrays/s  ETA 0:17   "
// else a line for logs:
//   "progress: 50/100 tiles (50%), 1.2 Mrays/s, ETA 0:17\n"
// `error` (e.g. "est. RMSE 0.0021 (target 0.002)"; may be empty) goes before the ETA.
std::string progress_text(const ProgressCounts& counts, const std::string& error, bool tty);

class Progress {
 public:
  using Clock = std::function<double()>;  // monotonic seconds

  // Draws on stderr with the steady clock.
  Progress(int64_t total, int64_t done_before);
  Progress(int64_t total, int64_t done_before, std::FILE* out, Clock clock);

  // Redraws with this client's counts so far, at most once per interval() unless `force`.
  // `error`: the estimated error so far, e.g. "est. RMSE 0.0021 (target 0.002)"; may be empty.
  void update(int64_t received, uint64_t rays, const std::string& error, bool force = false);
  // Blanks the bar (terminal only), before a line of other output.
  void clear_line();

  // Seconds between redraws: a bar can move often; a log should not fill with progress lines.
  static double interval(bool tty) { return tty ? 0.2 : 5.0; }

 private:
  int64_t total_, base_;
  std::FILE* out_;
  Clock clock_;
  bool tty_;
  double start_ = 0, last_ = -1e9;
};

}  // namespace tessera::cli

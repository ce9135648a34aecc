// SPDX-License-Identifier: Apache-2.0
#include "progress_line.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "duration_text.h"

namespace tessera::cli {
namespace {

const std::string kError = "est. RMSE 0.0021 (target 0.002)";

TEST(DurationText, MinutesUnderAnHourHoursFromAnHourOn) {
  EXPECT_EQ(format_duration(0), "0:00");
  EXPECT_EQ(format_duration(59.4), "0:59");
  EXPECT_EQ(format_duration(59.5), "1:00");  // rounded to the nearest second
  EXPECT_EQ(format_duration(754), "12:34");
  EXPECT_EQ(format_duration(3599.4), "59:59");
  EXPECT_EQ(format_duration(3600), "1:00:00");
  EXPECT_EQ(format_duration(3725), "1:02:05");
  EXPECT_EQ(format_duration(90061), "25:01:01");
}

TEST(DurationText, UnknownIsAQuestionMark) {
  EXPECT_EQ(format_duration(-1), "?");
  EXPECT_EQ(format_duration(NAN), "?");
  EXPECT_EQ(format_duration(INFINITY), "?");
}

// 20 tiles came through an earlier client, 30 here in 10 s: 50 of 100 done, 3 tiles/s over this
// client's own time, so the other 50 take 16.7 s; 12 Mrays in 10 s is 1.2 Mrays/s.
const ProgressCounts kHalfway{.total = 100, .done_before = 20, .received = 30, .rays = 12'000'000, .elapsed = 10};

TEST(ProgressLine, LogLineCountsEarlierTilesButRatesOnlyThisClients) {
  EXPECT_EQ(progress_text(kHalfway, "", false), "progress: 50/100 tiles (50%), 1.2 Mrays/s, ETA 0:17\n");
}

TEST(ProgressLine, LogLineShowsTheErrorBeforeTheEta) {
  EXPECT_EQ(progress_text(kHalfway, kError, false),
            "progress: 50/100 tiles (50%), 1.2 Mrays/s, est. RMSE 0.0021 (target 0.002), ETA 0:17\n");
}

TEST(ProgressLine, TerminalBarOverwritesItself) {
  EXPECT_EQ(progress_text(kHalfway, "", true),
            "\r[###############...............] 50/100 tiles  1.2 Mrays/s  ETA 0:17   ");
  EXPECT_EQ(progress_text(kHalfway, kError, true),
            "\r[###############...............] 50/100 tiles  1.2 Mrays/s  est. RMSE 0.0021 (target 0.002)  ETA 0:17   ");
}

TEST(ProgressLine, BarFillRoundsDown) {
  // 3 of 8 is 11.25 of 30 characters; one tile a second leaves 5 s.
  const ProgressCounts c{.total = 8, .done_before = 0, .received = 3, .rays = 0, .elapsed = 3};
  EXPECT_EQ(progress_text(c, "", true), "\r[###########...................] 3/8 tiles  0.0 Mrays/s  ETA 0:05   ");
  EXPECT_EQ(progress_text(c, "", false), "progress: 3/8 tiles (38%), 0.0 Mrays/s, ETA 0:05\n");
}

TEST(ProgressLine, NothingYetHasNoRateAndNoEta) {
  const ProgressCounts c{.total = 64, .done_before = 0, .received = 0, .rays = 0, .elapsed = 0};
  EXPECT_EQ(progress_text(c, "", false), "progress: 0/64 tiles (0%), 0.0 Mrays/s, ETA ?\n");
  EXPECT_EQ(progress_text(c, "", true), "\r[..............................] 0/64 tiles  0.0 Mrays/s  ETA ?   ");
}

TEST(ProgressLine, ResentTilesNeverCountPastTheTotal) {
  // 8 done before and 5 received (some re-sent): 10 of 10, nothing left.
  const ProgressCounts c{.total = 10, .done_before = 8, .received = 5, .rays = 0, .elapsed = 2};
  EXPECT_EQ(progress_text(c, "", false), "progress: 10/10 tiles (100%), 0.0 Mrays/s, ETA 0:00\n");
  EXPECT_EQ(progress_text(c, "", true), "\r[##############################] 10/10 tiles  0.0 Mrays/s  ETA 0:00   ");
}

TEST(ProgressLine, AJobWithoutTilesIsComplete) {
  const ProgressCounts c{.total = 0, .done_before = 0, .received = 0, .rays = 0, .elapsed = 1};
  EXPECT_EQ(progress_text(c, "", false), "progress: 0/0 tiles (100%), 0.0 Mrays/s, ETA ?\n");
  EXPECT_EQ(progress_text(c, "", true), "\r[##############################] 0/0 tiles  0.0 Mrays/s  ETA ?   ");
}

TEST(ProgressLine, LongEtaInHours) {
  const ProgressCounts c{.total = 3726, .done_before = 0, .received = 1, .rays = 2'500'000, .elapsed = 1};
  EXPECT_EQ(progress_text(c, "", false), "progress: 1/3726 tiles (0%), 2.5 Mrays/s, ETA 1:02:05\n");
}

// What a Progress drawing into a file (not a terminal) has written so far.
struct Capture {
  std::FILE* file = std::tmpfile();
  ~Capture() { std::fclose(file); }
  std::string text() const {
    std::fflush(file);
    std::string s(size_t(std::ftell(file)), '\0');
    std::rewind(file);
    s.resize(std::fread(s.data(), 1, s.size(), file));
    std::fseek(file, 0, SEEK_END);
    return s;
  }
};

TEST(Progress, LogLinesComeEveryFiveSecondsUnlessForced) {
  EXPECT_EQ(Progress::interval(false), 5.0);
  EXPECT_EQ(Progress::interval(true), 0.2);
  Capture out;
  ASSERT_NE(out.file, nullptr);
  double now = 100;
  Progress p(100, 20, out.file, [&] { return now; });
  now = 110;  // elapsed time counts from the Progress's construction
  p.update(30, 12'000'000, "");
  const std::string first = "progress: 50/100 tiles (50%), 1.2 Mrays/s, ETA 0:17\n";
  EXPECT_EQ(out.text(), first);
  now = 114.9;  // under 5 s since the last line: nothing
  p.update(40, 12'000'000, "");
  EXPECT_EQ(out.text(), first);
  now = 115;  // 5 s: the next line, 60/100 in 15 s
  p.update(40, 15'000'000, kError);
  const std::string second = first + "progress: 60/100 tiles (60%), 1.0 Mrays/s, " + kError + ", ETA 0:15\n";
  EXPECT_EQ(out.text(), second);
  now = 115.5;  // forced (the job's end): drawn at once
  p.update(80, 15'500'000, "", true);
  const std::string third = second + "progress: 100/100 tiles (100%), 1.0 Mrays/s, ETA 0:00\n";
  EXPECT_EQ(out.text(), third);
  p.clear_line();  // nothing to blank in a log
  EXPECT_EQ(out.text(), third);
}

}  // namespace
}  // namespace tessera::cli

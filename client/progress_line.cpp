// SPDX-License-Identifier: Apache-2.0
#include "progress_line.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>

#include "duration_text.h"

namespace tessera::cli {

namespace {

__attribute__((format(printf, 1, 2))) std::string printf_string(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);
  va_end(args);
  std::string s(size_t(std::max(n, 0)), '\0');
  std::vsnprintf(s.data(), s.size() + 1, format, again);
  va_end(again);
  return s;
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string progress_text(const ProgressCounts& c, const std::string& error, bool tty) {
  const double el = c.elapsed;
  const int64_t done = std::min(c.total, c.done_before + c.received);
  const double rate = el > 0 ? double(c.received) / el : 0;
  const double eta = rate > 0 ? double(c.total - done) / rate : NAN;
  const double mrays = el > 0 ? double(c.rays) / el / 1e6 : 0;
  if (tty) {
    const int width = 30;
    const int fill = c.total > 0 ? int(double(done) / double(c.total) * width) : width;
    return printf_string("\r[%s%s] %lld/%lld tiles  %.1f Mrays/s  %s%sETA %s   ",
                         std::string(size_t(fill), '#').c_str(), std::string(size_t(width - fill), '.').c_str(),
                         (long long)done, (long long)c.total, mrays, error.c_str(), error.empty() ? "" : "  ",
                         format_duration(eta).c_str());
  }
  return printf_string("progress: %lld/%lld tiles (%.0f%%), %.1f Mrays/s, %s%sETA %s\n", (long long)done,
                       (long long)c.total, c.total ? 100.0 * double(done) / double(c.total) : 100.0, mrays,
                       error.c_str(), error.empty() ? "" : ", ", format_duration(eta).c_str());
}

Progress::Progress(int64_t total, int64_t done_before) : Progress(total, done_before, stderr, steady_seconds) {}

Progress::Progress(int64_t total, int64_t done_before, std::FILE* out, Clock clock)
    : total_(total), base_(done_before), out_(out), clock_(std::move(clock)), tty_(isatty(fileno(out))) {
  start_ = clock_();
}

void Progress::update(int64_t received, uint64_t rays, const std::string& error, bool force) {
  const double t = clock_();
  if (!force && t - last_ < interval(tty_)) return;
  last_ = t;
  std::fputs(progress_text({total_, base_, received, rays, t - start_}, error, tty_).c_str(), out_);
  std::fflush(out_);
}

void Progress::clear_line() {
  if (tty_) std::fprintf(out_, "\r%80s\r", "");
}

}  // namespace tessera::cli

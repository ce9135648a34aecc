// SPDX-License-Identifier: Apache-2.0
#include "duration_text.h"

#include <cmath>
#include <cstdio>

namespace tessera::cli {

std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  char buf[32];
  const int t = int(std::lround(s));
  if (t >= 3600) {
    std::snprintf(buf, sizeof buf, "%d:%02d:%02d", t / 3600, t / 60 % 60, t % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%d:%02d", t / 60, t % 60);
  }
  return buf;
}

}  // namespace tessera::cli

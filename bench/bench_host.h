// SPDX-License-Identifier: Apache-2.0
// What every benchmark reports about the machine it ran on and measures with: the CPU's model
// name (printed next to every figure) and the process's CPU time.
#pragma once

#include <time.h>

#include <fstream>
#include <string>

namespace tessera::bench {

// /proc/cpuinfo's "model name", or "unknown".
inline std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown";
}

// CPU time of every thread of the process, user and system, to the nanosecond: on a shared
// machine what the work costs even while other processes take the cores away.
inline double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace tessera::bench

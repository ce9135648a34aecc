// SPDX-License-Identifier: Apache-2.0
#include "cpu_quota.h"

#include <sched.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <thread>

namespace tessera::worker {

std::optional<int> cores_from_cfs(long long quota_us, long long period_us) {
  if (quota_us <= 0 || period_us <= 0) return std::nullopt;
  return int(std::max<long long>(1, (quota_us + period_us - 1) / period_us));
}

std::optional<int> cores_from_cpu_max(const std::string& line) {
  std::istringstream in(line);
  std::string quota;
  long long period = 0;
  if (!(in >> quota >> period) || quota == "max") return std::nullopt;
  try {
    return cores_from_cfs(std::stoll(quota), period);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

namespace {

std::optional<int> cgroup_cores() {
  // cgroup v2 (what Docker and Kubernetes use on current hosts): the process's own cgroup is
  // mounted at /sys/fs/cgroup inside a container.
  if (std::ifstream f("/sys/fs/cgroup/cpu.max"); f) {
    std::string line;
    std::getline(f, line);
    return cores_from_cpu_max(line);
  }
  std::ifstream q("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"), p("/sys/fs/cgroup/cpu/cpu.cfs_period_us");
  long long quota = 0, period = 0;
  if (q >> quota && p >> period) return cores_from_cfs(quota, period);
  return std::nullopt;
}

}  // namespace

int available_cores() {
  int cores = int(std::max(1u, std::thread::hardware_concurrency()));
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) cores = std::min(cores, std::max(1, CPU_COUNT(&set)));
  if (auto quota = cgroup_cores()) cores = std::min(cores, *quota);
  return std::max(1, cores);
}

}  // namespace tessera::worker

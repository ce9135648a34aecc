// SPDX-License-Identifier: Apache-2.0
// How many render threads this process can actually use. std::thread::hardware_concurrency()
// counts the host's cores, but a worker in a container is usually limited by its CPU affinity
// (docker --cpuset-cpus) or by a CFS quota (docker --cpus, Kubernetes resources.limits.cpu).
// Running more threads than the quota allows only adds throttling and context switches.
#pragma once

#include <optional>
#include <string>

namespace tessera::worker {

// Cores granted by a cgroup v2 `cpu.max` line ("QUOTA PERIOD" or "max PERIOD"), rounded up;
// nullopt when unlimited or malformed.
std::optional<int> cores_from_cpu_max(const std::string& line);

// Cores granted by cgroup v1 cpu.cfs_quota_us / cpu.cfs_period_us (quota -1 = unlimited).
std::optional<int> cores_from_cfs(long long quota_us, long long period_us);

// min(hardware threads, CPUs in this process's affinity mask, the cgroup quota), at least 1.
int available_cores();

}  // namespace tessera::worker

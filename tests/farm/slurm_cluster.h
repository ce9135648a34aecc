// SPDX-License-Identifier: Apache-2.0
// A single-node Slurm on localhost for the tests: munged with its own key and socket, slurmctld
// and slurmd in the foreground with a configuration in a temporary folder, on free ports, as root
// (slurmd starts jobs as their users). Everything dies with the test (the harness's Process).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "farm_harness.h"

namespace tessera::farmtest {

class SlurmCluster {
 public:
  // Why a single-node Slurm cannot run here at all (not root, a program missing), or nullopt.
  static std::optional<std::string> cannot_run();

  // Starts the three daemons under `dir` and waits (up to 30 s) for the node to be idle. Throws
  // std::runtime_error with the daemons' logs when they do not come up.
  explicit SlurmCluster(const fs::path& dir);
  ~SlurmCluster();

  // Runs a shell command with SLURM_CONF pointing at this cluster; returns its exit status and
  // what it printed (stdout and stderr).
  CliResult run(const std::string& command) const;
  // `scontrol show job -o ID`: one line per job (an array: one per task).
  std::string show_job(const std::string& id) const;
  std::string logs() const;
  const fs::path& conf() const { return conf_; }

 private:
  fs::path dir_, conf_;
  std::unique_ptr<Process> munged_, slurmctld_, slurmd_;
};

}  // namespace tessera::farmtest

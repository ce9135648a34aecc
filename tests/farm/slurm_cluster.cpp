// SPDX-License-Identifier: Apache-2.0
#include "slurm_cluster.h"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <random>
#include <stdexcept>
#include <thread>

namespace tessera::farmtest {

using namespace std::chrono_literals;

namespace {

std::optional<fs::path> on_path(const std::string& name) {
  for (const char* dir : {"/usr/sbin", "/usr/bin", "/sbin", "/bin", "/usr/local/sbin", "/usr/local/bin"}) {
    const fs::path p = fs::path(dir) / name;
    if (access(p.c_str(), X_OK) == 0) return p;
  }
  return std::nullopt;
}

std::string short_hostname() {
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  std::string h = host;
  return h.substr(0, h.find('.'));
}

}  // namespace

std::optional<std::string> SlurmCluster::cannot_run() {
  if (geteuid() != 0) return "a single-node Slurm needs root here (slurmd starts jobs as their users)";
  for (const char* exe : {"munged", "slurmctld", "slurmd", "sbatch", "scontrol"}) {
    if (!on_path(exe)) {
      return std::string(exe) + " is not installed (scripts/install-deps.sh installs slurm-wlm and munge)";
    }
  }
  return std::nullopt;
}

SlurmCluster::SlurmCluster(const fs::path& dir) : dir_(dir), conf_(dir / "slurm.conf") {
  fs::create_directories(dir_ / "state");
  fs::create_directories(dir_ / "spool");
  // munged: a key of our own (munged wants it private to its user), its socket in our folder.
  {
    std::ofstream key(dir_ / "munge.key", std::ios::binary);
    std::random_device rd;
    for (int i = 0; i < 1024; ++i) key.put(char(rd() & 0xff));
  }
  fs::permissions(dir_ / "munge.key", fs::perms::owner_read);
  const std::string sock = (dir_ / "munge.sock").string();
  munged_ = std::make_unique<Process>(
      std::vector<std::string>{on_path("munged")->string(), "--foreground", "--force",
                               "--key-file=" + (dir_ / "munge.key").string(), "--socket=" + sock,
                               "--pid-file=" + (dir_ / "munged.pid").string(),
                               "--log-file=" + (dir_ / "munged.log").string(),
                               "--seed-file=" + (dir_ / "munge.seed").string()},
      dir_ / "munged.out");
  for (int i = 0; i < 100 && !fs::exists(sock); ++i) std::this_thread::sleep_for(50ms);
  if (!fs::exists(sock)) throw std::runtime_error("munged did not start:\n" + logs());

  const std::string host = short_hostname();
  const unsigned cpus = std::max(1u, std::thread::hardware_concurrency());
  std::ofstream conf(conf_);
  conf << "ClusterName=tessera-test\n"
       << "SlurmctldHost=" << host << "(127.0.0.1)\n"
       << "AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket=" << sock << "\n"
       << "SlurmUser=root\nSlurmdUser=root\n"
       << "SlurmctldPort=" << free_port() << "\nSlurmdPort=" << free_port() << "\n"
       << "StateSaveLocation=" << (dir_ / "state").string() << "\n"
       << "SlurmdSpoolDir=" << (dir_ / "spool").string() << "\n"
       << "SlurmctldPidFile=" << (dir_ / "slurmctld.pid").string() << "\n"
       << "SlurmdPidFile=" << (dir_ / "slurmd.pid").string() << "\n"
       << "SlurmctldLogFile=" << (dir_ / "slurmctld.log").string() << "\n"
       << "SlurmdLogFile=" << (dir_ / "slurmd.log").string() << "\n"
       // No cgroups (containers and CI machines may not delegate them): process groups, no binding.
       << "ProctrackType=proctrack/pgid\nTaskPlugin=task/none\n"
       << "SelectType=select/cons_tres\nSelectTypeParameters=CR_CPU\n"
       << "AccountingStorageType=accounting_storage/none\nJobAcctGatherType=jobacct_gather/none\n"
       << "JobCompType=jobcomp/none\nMpiDefault=none\nReturnToService=2\n"
       << "MinJobAge=600\n"  // finished jobs stay visible to scontrol for the test
       << "NodeName=" << host << " NodeAddr=127.0.0.1 CPUs=" << cpus << " State=UNKNOWN\n"
       << "PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n";
  conf.close();
  slurmctld_ = std::make_unique<Process>(
      std::vector<std::string>{on_path("slurmctld")->string(), "-D", "-i", "-f", conf_.string()}, dir_ / "slurmctld.out");
  slurmd_ = std::make_unique<Process>(std::vector<std::string>{on_path("slurmd")->string(), "-D", "-f", conf_.string()},
                                      dir_ / "slurmd.out");
  for (int i = 0; i < 300; ++i) {
    if (!slurmctld_->running() || !slurmd_->running()) throw std::runtime_error("a Slurm daemon exited:\n" + logs());
    const CliResult r = run("sinfo -h -o %T");
    if (r.code == 0 && r.output.find("idle") != std::string::npos) return;
    std::this_thread::sleep_for(100ms);
  }
  throw std::runtime_error("the Slurm node did not come up in 30 s:\n" + logs());
}

SlurmCluster::~SlurmCluster() {
  // slurmd first: no new steps; then the controller, then munge.
  for (auto* p : {slurmd_.get(), slurmctld_.get(), munged_.get()}) {
    if (p) {
      p->signal(SIGTERM);
      p->wait(5s);
    }
  }
}

CliResult SlurmCluster::run(const std::string& command) const {
  CliResult r;
  const std::string cmd = "export SLURM_CONF='" + conf_.string() + "'; { " + command + "; } 2>&1";
  FILE* f = popen(cmd.c_str(), "r");
  if (!f) return {127, "popen failed"};
  std::array<char, 4096> buf{};
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), f)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(f);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string SlurmCluster::show_job(const std::string& id) const { return run("scontrol show job -o " + id).output; }

std::string SlurmCluster::logs() const {
  std::string all;
  for (const char* f : {"munged.out", "munged.log", "slurmctld.out", "slurmctld.log", "slurmd.out", "slurmd.log"}) {
    const fs::path p = dir_ / f;
    if (fs::exists(p)) all += "--- " + std::string(f) + "\n" + read_text(p) + "\n";
  }
  return all;
}

}  // namespace tessera::farmtest

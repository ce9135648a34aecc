// SPDX-License-Identifier: Apache-2.0
// `tessera watch JOB [-o OUT]`: re-attaches to a job submitted earlier (by `submit --detach`, or
// a client that died): shows its progress and, with -o, writes and acknowledges its frames.
#include <memory>
#include <string>

#include "commands.h"
#include "farm_command.h"
#include "output_flags.h"
#include "watch_job.h"

namespace tessera::cli {

namespace v1 = tessera::v1;

namespace {

struct WatchArgs {
  std::string coordinator, job, output;
  SecurityFlags security;
  bool quiet = false;
  bool error_channels = false;
  double preview_every = 0;
  color::OutputOptions color;
};

int run_watch(const WatchArgs& a) {
  FarmClient client = connect(a.coordinator, a.security);
  const v1::JobStatus st = get_job(client, a.job);
  if (!a.output.empty()) check_output_writable(a.output, st.first_frame());
  return watch_job(client, a.job, {a.output, st.name(), a.quiet, a.color, a.error_channels, a.preview_every});
}

}  // namespace

void register_watch_command(CLI::App& app) {
  auto a = std::make_shared<WatchArgs>();
  CLI::App* cmd = app.add_subcommand("watch", "Re-attach to a job: progress, and its frames with -o");
  cmd->add_option("job", a->job, "Job id")->required();
  cmd->add_option("-o,--output", a->output, "Write frames here ('#' runs become the frame number)");
  add_coordinator_option(cmd, &a->coordinator, &a->security);
  cmd->add_flag("-q,--quiet", a->quiet, "No progress display");
  add_frame_output_options(cmd, &a->error_channels, &a->preview_every);
  add_output_options(*cmd, a->color);
  cmd->callback([a] { guarded("watch", [&] { return run_watch(*a); }); });
}

}  // namespace tessera::cli

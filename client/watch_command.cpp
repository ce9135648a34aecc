// SPDX-License-Identifier: Apache-2.0
// `tessera watch JOB [-o OUT]`: re-attaches to a job submitted earlier (by `submit --detach`, or
// a client that died): shows its progress and, with -o, writes and acknowledges its frames.
#include <memory>
#include <string>

#include "commands.h"
#include "farm_command.h"
#include "job_output.h"
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
  WatchOptions o{a.output, st.name(), a.quiet, a.color, a.error_channels, a.preview_every};
  if (a.output.empty() && st.has_output()) {
    // Without -o, the output recorded with the job, with its options (the flags given here do
    // not mix with them: -o takes the job's frames elsewhere, with these flags).
    const RecordedOutput r = from_job_output(st.output());
    o.output = r.pattern;
    o.color = r.color;
    o.error_channels = r.error_channels;
    if (!a.quiet) std::printf("writing frames to %s (recorded with the job)\n", r.pattern.c_str());
  }
  if (!o.output.empty()) check_output_writable(o.output, st.first_frame());
  return watch_job(client, a.job, o);
}

}  // namespace

void register_watch_command(CLI::App& app) {
  auto a = std::make_shared<WatchArgs>();
  CLI::App* cmd = app.add_subcommand("watch", "Re-attach to a job: progress, and its frames with -o");
  cmd->add_option("job", a->job, "Job id")->required();
  cmd->add_option("-o,--output", a->output,
                  "Write frames here ('#' runs become the frame number); default: the output recorded with the "
                  "job by `tessera submit -o`, with its options");
  add_coordinator_option(cmd, &a->coordinator, &a->security);
  cmd->add_flag("-q,--quiet", a->quiet, "No progress display");
  add_frame_output_options(cmd, &a->error_channels, &a->preview_every);
  add_output_options(*cmd, a->color);
  cmd->callback([a] { guarded("watch", [&] { return run_watch(*a); }); });
}

}  // namespace tessera::cli

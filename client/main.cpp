// SPDX-License-Identifier: Apache-2.0
// `tessera`: the command-line client. Subcommands live in their own files (commands.h).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "commands.h"
#include "farm/command_line.h"
#include "interrupt.h"

int main(int argc, char** argv) {
  tessera::cli::take_interrupts();  // first: before gRPC starts any thread
  CLI::App app{"tessera: render scenes locally or on a Tessera render farm"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "tessera 0.1.0");
  tessera::cli::register_render_command(app);
  tessera::cli::register_color_commands(app);
  tessera::cli::register_submit_command(app);
  tessera::cli::register_watch_command(app);
  tessera::cli::register_collect_command(app);
  tessera::cli::register_job_commands(app);
  tessera::cli::register_listing_commands(app);
  tessera::cli::register_health_command(app);
  tessera::cli::register_rays_command(app);
  try {
    // A bad command line exits 2 as docs/farm.md promises; a command's own code passes through.
    if (const std::optional<int> rc = tessera::farm::parse_command_line(app, argc, argv)) return *rc;
  } catch (const std::exception& e) {
    // Subcommands report their own errors; this is the last line of defence.
    std::cerr << "tessera: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

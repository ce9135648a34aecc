// SPDX-License-Identifier: Apache-2.0
// Each family of `tessera` subcommands registers itself on the CLI11 app.
#pragma once

#include <CLI/CLI.hpp>

namespace tessera::cli {

void register_render_command(CLI::App& app);    // render_command.cpp: in-process render
void register_color_commands(CLI::App& app);    // color_commands.cpp: convert, palette-fade
void register_submit_command(CLI::App& app);    // submit_command.cpp: a scene to the farm, then watch it
void register_watch_command(CLI::App& app);     // watch_command.cpp: re-attach to a farm job
void register_collect_command(CLI::App& app);   // collect_command.cpp: deliver jobs' frames to their recorded outputs
void register_job_commands(CLI::App& app);      // job_commands.cpp: status, cancel, priority
void register_listing_commands(CLI::App& app);  // listing_commands.cpp: workers, rayservers
void register_health_command(CLI::App& app);    // health_command.cpp: the coordinator's gRPC health service
void register_rays_command(CLI::App& app);      // rays_command.cpp: ray queries, in-process or on tessera-rays

}  // namespace tessera::cli

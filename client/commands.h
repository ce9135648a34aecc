// Each family of `tessera` subcommands registers itself on the CLI11 app.
#pragma once

#include <CLI/CLI.hpp>

namespace tessera::cli {

void register_render_command(CLI::App& app);  // render_command.cpp: in-process render
void register_color_commands(CLI::App& app);  // color_commands.cpp: convert, palette-fade
void register_farm_commands(CLI::App& app);   // farm_commands.cpp: submit, ..., workers, rayservers
void register_health_command(CLI::App& app);  // health_command.cpp: the coordinator's gRPC health service
void register_rays_command(CLI::App& app);    // rays_command.cpp: ray queries, in-process or on tessera-rays

}  // namespace tessera::cli

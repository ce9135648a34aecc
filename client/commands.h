// Each family of `tessera` subcommands registers itself on the CLI11 app.
#pragma once

#include <CLI/CLI.hpp>

namespace tessera::cli {

void register_render_command(CLI::App& app);  // render_command.cpp: in-process render
void register_color_commands(CLI::App& app);  // color_commands.cpp: convert, palette-fade
void register_farm_commands(CLI::App& app);   // farm_commands.cpp: submit, watch, status, cancel, workers
void register_health_command(CLI::App& app);  // health_command.cpp: the coordinator's gRPC health service

}  // namespace tessera::cli

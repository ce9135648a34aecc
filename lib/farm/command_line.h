// SPDX-License-Identifier: Apache-2.0
// Parsing a farm program's command line (tessera, tessera-server, tessera-worker, tessera-rays).
#pragma once

#include <CLI/CLI.hpp>

#include <optional>

namespace tessera::farm {

// Parses argv into `app`: nullopt to go on, else the exit code to leave with. CLI11 prints the
// message naming the flag (or the help, or the version). A bad command line is bad input and
// exits 2, as the programs' other bad input does (a bad token file, TLS files that do not
// match), not with CLI11's own codes (104-109); --help and --version exit 0. A subcommand's
// callback that ends with CLI::RuntimeError(code) (its message already printed) leaves with its
// own code.
inline std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
#include "command_error.h"

#include <CLI/CLI.hpp>

#include <iostream>

namespace tessera::cli {

void guarded(const char* name, const std::function<int()>& command) {
  int rc = 0;
  try {
    rc = command();
  } catch (const CommandError& e) {
    std::cerr << "tessera " << name << ": " << e.message << "\n";
    rc = e.code;
  }
  if (rc != 0) throw CLI::RuntimeError(rc);
}

}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
// The flags that fill color::OutputOptions, shared by every command that writes a frame
// (`tessera convert`, `render`, `submit`, `watch`): one set of names, defaults and range checks.
// Parsing command lines is the program's business, so these live with the client and not in
// lib/color, which resolves the filled options (color/output_options.h).
#pragma once

#include <CLI/CLI.hpp>

#include "color/output_options.h"

namespace tessera::cli {

// Adds --tonemap, --exposure, --white, --format, --colors, --dither and --report.
void add_output_options(CLI::App& command, color::OutputOptions& options);

}  // namespace tessera::cli

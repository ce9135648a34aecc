// Placeholder until the farm work (issue 3) lands its commands.
#include "commands.h"

namespace tessera::cli {
void register_farm_commands(CLI::App&) {}
}  // namespace tessera::cli

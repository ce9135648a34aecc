// SPDX-License-Identifier: Apache-2.0
// The CLI's one error path. A command that cannot do what was asked throws CommandError (its
// exit code and a message); guarded(), around every command, prints "tessera NAME: message" on
// stderr and exits with the code. A command that answered (`tessera health`: not serving) may
// also return a non-zero code itself, having said why.
// Exit codes: 0 done, 1 failure (network, I/O), 2 bad input (scene, arguments), 3 job cancelled.
#pragma once

#include <functional>
#include <string>

namespace tessera::cli {

inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitCancelled = 3;

struct CommandError {
  int code;
  std::string message;
};

// Runs a command (`name` as typed: "render", "watch", ...), turning CommandError and a non-zero
// return into the exit code for CLI11.
void guarded(const char* name, const std::function<int()>& command);

}  // namespace tessera::cli

// What every farm subcommand (`tessera submit | watch | status | cancel | priority | workers |
// rayservers`) shares: its exit codes, its error, the coordinator and security flags, the
// connection they give, and the wrapper that turns a failure into a message and an exit code.
// Exit codes: 0 done, 1 failure (network, I/O), 2 bad input (scene, arguments), 3 job cancelled.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>

#include "farm_client.h"

namespace tessera::cli {

inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitCancelled = 3;

// Thrown by a farm command; `guarded` prints "tessera NAME: message" and exits with `code`.
struct FarmError {
  int code;
  std::string message;
};

// A failed call about one job: an unknown job id is the user's input error (exit 2).
FarmError job_error(const FarmClient& client, const grpc::Status& s, const std::string& what);

// The client for a command's --coordinator and security flags; bad certificate or token files
// are input errors (exit 2).
FarmClient connect(const std::string& coordinator, const SecurityFlags& flags);

// The job's status from the coordinator (GetJob); FarmError when the call fails (exit 2 for an
// unknown job id).
tessera::v1::JobStatus get_job(FarmClient& client, const std::string& job);

// Adds --coordinator and the security flags (add_security_flags).
void add_coordinator_option(CLI::App* cmd, std::string* target, SecurityFlags* security);

// Adds --token-file, --tls-ca, --tls-cert and --tls-key (help group "Security"), the same for
// every command that talks to a server. `peer` names the servers in the help.
void add_security_flags(CLI::App* cmd, SecurityFlags* security, const std::string& peer = "coordinator");

// Runs a command, turning FarmError into a message and an exit code for CLI11.
void guarded(const char* name, const std::function<int()>& command);

}  // namespace tessera::cli

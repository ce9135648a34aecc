// SPDX-License-Identifier: Apache-2.0
// What every farm subcommand (`tessera submit | watch | status | cancel | priority | workers |
// rayservers`, and `health` and `rays` for their flags) shares: the coordinator and security
// flags, the connection they give, and the errors of its calls (command_error.h).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "command_error.h"
#include "farm_client.h"

namespace tessera::cli {

// A failed call about one job: an unknown job id is the user's input error (exit 2).
CommandError job_error(const FarmClient& client, const grpc::Status& s, const std::string& what);

// The client for a command's --coordinator and security flags; bad certificate or token files
// are input errors (exit 2).
FarmClient connect(const std::string& coordinator, const SecurityFlags& flags);

// The job's status from the coordinator (GetJob); CommandError when the call fails (exit 2 for an
// unknown job id).
tessera::v1::JobStatus get_job(FarmClient& client, const std::string& job);

// Adds --coordinator and the security flags (add_security_flags).
void add_coordinator_option(CLI::App* cmd, std::string* target, SecurityFlags* security);

// Adds --token-file, --tls-ca, --tls-cert and --tls-key (help group "Security"), the same for
// every command that talks to a server. `peer` names the servers in the help.
void add_security_flags(CLI::App* cmd, SecurityFlags* security, const std::string& peer = "coordinator");

}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
// Named client tokens (`tessera-server --client-tokens PATH`): each client gets its own token,
// and the name it is filed under becomes the client's identity ("token:NAME"): the owner of the
// jobs it submits, the key of its job quota. Without TLS client certificates this is how several
// people share a farm without being able to cancel each other's jobs.
//
// PATH is either a file with one `name:token` per line (blank lines and lines starting with '#'
// are skipped), or a directory holding one file per client: the file's name is the client's
// name, its content (trimmed) the token. Hidden files (".x") in the directory are skipped.
#pragma once

#include <map>
#include <string>

#include "farm/farm_error.h"

namespace tessera::farm {

// name -> token. Throws FarmError naming the file (and line) for an unreadable path, a
// line without ':', an empty name or token, a name used twice, or one token given to two names.
std::map<std::string, std::string> read_client_tokens(const std::string& path);

}  // namespace tessera::farm

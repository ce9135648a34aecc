// SPDX-License-Identifier: Apache-2.0
// lib/farm's exception: what the shared room throws when it cannot do what was asked (a token or
// certificate file that cannot be read, security flags that do not go together, a malformed
// client token list), with a message naming the file, line or flag. A std::runtime_error, so
// callers that catch those keep working; the programs turn it into an exit code at their edge.
// BundleError and FetchError are the same thing, made precise.
#pragma once

#include <stdexcept>

namespace tessera::farm {

class FarmError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace tessera::farm

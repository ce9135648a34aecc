// SPDX-License-Identifier: Apache-2.0
// lib/rays' exception: what ray queries and ray files throw when they cannot do what was asked
// (a malformed CSV or .npy file, an unknown hit field, a response whose arrays do not hold the
// rays asked), with a message naming the file, line, column or field. A std::runtime_error, so
// callers that catch those keep working; the CLI turns it into an exit code, the ray service into
// a status.
#pragma once

#include <stdexcept>

namespace tessera::rays {

class RaysError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace tessera::rays

// SPDX-License-Identifier: Apache-2.0
// The one error type for bad scene input: its message names the file, the JSON path (or line)
// and what is allowed, e.g. "scenes/a.json: objects[3].radius: must be > 0, got -1".
#pragma once

#include <stdexcept>
#include <string>

namespace tessera {

class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// The one exception type of the color code: bad options, unreadable or unwritable files.
#pragma once

#include <stdexcept>

namespace tessera::color {

class ColorError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace tessera::color

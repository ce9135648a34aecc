// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_table.h"

namespace tessera::rays {

std::string name_of(const std::vector<std::string>& names, uint32_t i) {
  if (i == kNoIndex) return "";
  if (i < names.size() && !names[i].empty()) return names[i];
  return "#" + std::to_string(i);
}

}  // namespace tessera::rays

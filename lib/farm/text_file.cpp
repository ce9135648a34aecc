// SPDX-License-Identifier: Apache-2.0
#include "farm/text_file.h"

#include <fstream>
#include <sstream>

#include "farm/farm_error.h"

namespace tessera::farm {

std::string read_text_file(const std::filesystem::path& path, std::string_view what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw FarmError("cannot read " + (what.empty() ? std::string() : std::string(what) + " ") + path.string());
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string trim_blanks(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string_view::npos) return {};
  return std::string(s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1));
}

}  // namespace tessera::farm

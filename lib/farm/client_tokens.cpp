// SPDX-License-Identifier: Apache-2.0
#include "farm/client_tokens.h"

#include <cctype>
#include <filesystem>
#include <set>
#include <sstream>

#include "farm/farm_error.h"
#include "farm/text_file.h"

namespace tessera::farm {

namespace fs = std::filesystem;

namespace {

// Names end up in logs and in the database as "token:NAME": keep them printable and short.
void check_name(const std::string& name, const std::string& where) {
  if (name.empty() || name.size() > 64) throw FarmError(where + ": a client name must be 1-64 characters");
  for (char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.' || c == '@')) {
      throw FarmError(where + ": client name '" + name + "' may only hold letters, digits and - _ . @");
    }
  }
}

}  // namespace

std::map<std::string, std::string> read_client_tokens(const std::string& path) {
  std::map<std::string, std::string> out;
  std::set<std::string> tokens;
  auto add = [&](const std::string& name, const std::string& token, const std::string& where) {
    check_name(name, where);
    if (token.empty()) throw FarmError(where + ": the token of client '" + name + "' is empty");
    if (!out.emplace(name, token).second) throw FarmError(where + ": client '" + name + "' appears twice");
    if (!tokens.insert(token).second) {
      throw FarmError(where + ": client '" + name + "' has the same token as another client");
    }
  };
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    for (const auto& e : fs::directory_iterator(path, ec)) {
      const std::string name = e.path().filename().string();
      if (name.empty() || name[0] == '.' || !e.is_regular_file()) continue;
      add(name, trim_blanks(read_text_file(e.path(), "the client token file")), e.path().string());
    }
    if (ec) throw FarmError("cannot list the client token directory " + path + ": " + ec.message());
  } else {
    std::istringstream in(read_text_file(path, "the client token file"));
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      const std::string t = trim_blanks(line);
      if (t.empty() || t[0] == '#') continue;
      const std::string where = path + " line " + std::to_string(n);
      const auto colon = t.find(':');
      if (colon == std::string::npos) throw FarmError(where + ": expected name:token");
      add(trim_blanks(t.substr(0, colon)), trim_blanks(t.substr(colon + 1)), where);
    }
  }
  if (out.empty()) throw FarmError("the client tokens " + path + " name no client");
  return out;
}

}  // namespace tessera::farm

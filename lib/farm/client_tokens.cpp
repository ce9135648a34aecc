#include "farm/client_tokens.h"

#include <cctype>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace tessera::farm {

namespace fs = std::filesystem;

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read the client token file " + p.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Names end up in logs and in the database as "token:NAME": keep them printable and short.
void check_name(const std::string& name, const std::string& where) {
  if (name.empty() || name.size() > 64) throw std::runtime_error(where + ": a client name must be 1-64 characters");
  for (char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.' || c == '@')) {
      throw std::runtime_error(where + ": client name '" + name + "' may only hold letters, digits and - _ . @");
    }
  }
}

}  // namespace

std::map<std::string, std::string> read_client_tokens(const std::string& path) {
  std::map<std::string, std::string> out;
  std::set<std::string> tokens;
  auto add = [&](const std::string& name, const std::string& token, const std::string& where) {
    check_name(name, where);
    if (token.empty()) throw std::runtime_error(where + ": the token of client '" + name + "' is empty");
    if (!out.emplace(name, token).second) throw std::runtime_error(where + ": client '" + name + "' appears twice");
    if (!tokens.insert(token).second) {
      throw std::runtime_error(where + ": client '" + name + "' has the same token as another client");
    }
  };
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    for (const auto& e : fs::directory_iterator(path, ec)) {
      const std::string name = e.path().filename().string();
      if (name.empty() || name[0] == '.' || !e.is_regular_file()) continue;
      add(name, trim(slurp(e.path())), e.path().string());
    }
    if (ec) throw std::runtime_error("cannot list the client token directory " + path + ": " + ec.message());
  } else {
    std::istringstream in(slurp(path));
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      const std::string t = trim(line);
      if (t.empty() || t[0] == '#') continue;
      const std::string where = path + " line " + std::to_string(n);
      const auto colon = t.find(':');
      if (colon == std::string::npos) throw std::runtime_error(where + ": expected name:token");
      add(trim(t.substr(0, colon)), trim(t.substr(colon + 1)), where);
    }
  }
  if (out.empty()) throw std::runtime_error("the client tokens " + path + " name no client");
  return out;
}

}  // namespace tessera::farm

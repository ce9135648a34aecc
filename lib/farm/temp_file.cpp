// SPDX-License-Identifier: Apache-2.0
#include "farm/temp_file.h"

#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <system_error>
#include <vector>

namespace tessera::farm {

namespace fs = std::filesystem;

namespace {
std::vector<char> name_template(const fs::path& dir, const std::string& stem, const std::string& suffix) {
  const std::string t = (dir / (stem + ".XXXXXX" + suffix)).string();
  return std::vector<char>(t.c_str(), t.c_str() + t.size() + 1);
}
}  // namespace

fs::path make_temp_file(const fs::path& dir, const std::string& stem, const std::string& suffix, TempAccess access) {
  std::vector<char> name = name_template(dir, stem, suffix);
  const int fd = mkstemps(name.data(), int(suffix.size()));
  if (fd < 0) {
    throw fs::filesystem_error("cannot create a file in", dir, std::error_code(errno, std::generic_category()));
  }
  if (access == TempAccess::kReadable) fchmod(fd, 0644);
  close(fd);
  return fs::path(name.data());
}

fs::path make_temp_dir(const fs::path& parent, const std::string& stem) {
  std::vector<char> name = name_template(parent, stem, "");
  if (!mkdtemp(name.data())) {
    throw fs::filesystem_error("cannot create a folder in", parent, std::error_code(errno, std::generic_category()));
  }
  return fs::path(name.data());
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
// Files and folders written beside their final name and renamed into place, so a reader never
// sees half of one. Their names are made by the C library (mkstemps, mkdtemp), which creates the
// file or folder atomically under a name no other process or thread holds.
#pragma once

#include <filesystem>
#include <string>

namespace tessera::farm {

// A new, empty file "<stem>.XXXXXX<suffix>" in `dir` (the suffix keeps an extension that says the
// file's format). mkstemps makes it readable by its owner only; `readable` makes it 0644, as a
// user's output file is when written directly. Throws std::filesystem::filesystem_error naming
// the folder.
enum class TempAccess { kOwner, kReadable };
std::filesystem::path make_temp_file(const std::filesystem::path& dir, const std::string& stem,
                                     const std::string& suffix = "", TempAccess access = TempAccess::kOwner);
// A new, empty folder "<stem>.XXXXXX" in `parent`. Throws std::filesystem::filesystem_error.
std::filesystem::path make_temp_dir(const std::filesystem::path& parent, const std::string& stem);

// Writes `path` through `write(temp_path)` into "<stem>.tmp.XXXXXX<extension>" beside it (the
// extension kept, so a writer that picks the format from it still can), then renames it into
// place: a reader, or a process killed mid-write, never leaves half a file under `path`. A write
// that throws leaves nothing behind and the exception goes on.
template <class Write>
void write_in_place(const std::filesystem::path& path, Write&& write, TempAccess access = TempAccess::kReadable) {
  const std::filesystem::path tmp = make_temp_file(path.parent_path().empty() ? "." : path.parent_path(),
                                                   path.stem().string() + ".tmp", path.extension().string(), access);
  try {
    write(tmp.string());
    std::filesystem::rename(tmp, path);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
}

}  // namespace tessera::farm

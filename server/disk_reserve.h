// SPDX-License-Identifier: Apache-2.0
// Space held back on the data disk for SQLite (<data-dir>/.reserve, a few hundred KiB). When the
// disk fills up completely, SQLite can no longer checkpoint its WAL (the database file must grow
// a little), so the WAL can no longer be cut back, and nothing could ever be written again,
// acknowledgements included, even with nothing left to delete. Giving the reserve back breaks
// that deadlock; it is set aside again after the next successful write.
#pragma once

#include <sys/types.h>

#include <filesystem>

namespace tessera::server {

class DiskReserve {
 public:
  static constexpr off_t kBytes = 512 * 1024;

  explicit DiskReserve(std::filesystem::path file) : file_(std::move(file)) {}

  // Sets the space aside unless the file is there already. When the disk has no room for it,
  // wanted() turns true: try again after the next successful write.
  void make();
  // Gives the space back (deletes the file; says so when there was one).
  void release();
  // Should make() be tried again (it failed, or the store recovered from a full disk)?
  bool wanted() const { return wanted_; }
  void want() { wanted_ = true; }

 private:
  std::filesystem::path file_;
  bool wanted_ = false;
};

}  // namespace tessera::server

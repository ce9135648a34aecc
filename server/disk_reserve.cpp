// SPDX-License-Identifier: Apache-2.0
#include "disk_reserve.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

namespace tessera::server {

namespace fs = std::filesystem;

void DiskReserve::make() {
  wanted_ = false;
  std::error_code ec;
  if (fs::exists(file_, ec)) return;
  const int fd = ::open(file_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return;
  const bool ok = ::posix_fallocate(fd, 0, kBytes) == 0 && ::fsync(fd) == 0;
  ::close(fd);
  if (!ok) {
    ::unlink(file_.c_str());
    wanted_ = true;  // try again after the next successful batch
    spdlog::warn("cannot set aside {} KiB on the data disk (full?): will try again", kBytes / 1024);
  }
}

void DiskReserve::release() {
  if (::unlink(file_.c_str()) == 0) {
    spdlog::warn("disk full: gave back the {} KiB reserve so that the database can checkpoint", kBytes / 1024);
  }
}

}  // namespace tessera::server

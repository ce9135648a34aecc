#include "tile_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace tessera::server {

namespace fs = std::filesystem;

namespace {
[[noreturn]] void fail(const std::string& what, const fs::path& p, int err) {
  throw std::runtime_error(what + " " + p.string() + ": " + std::strerror(err));
}
}  // namespace

TileStore::TileStore(fs::path root) : root_(std::move(root)) {
  std::error_code ec;
  fs::create_directories(root_, ec);
  if (ec) throw std::runtime_error("cannot create the tile directory " + root_.string() + ": " + ec.message());
  root_fd_ = ::open(root_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (root_fd_ < 0) fail("cannot open the tile directory", root_, errno);
}

TileStore::~TileStore() {
  if (root_fd_ >= 0) ::close(root_fd_);
}

fs::path TileStore::path(const std::string& job, int frame, int tile) const {
  return root_ / job / (std::to_string(frame) + "-" + std::to_string(tile) + ".tile");
}

void TileStore::write(const std::string& job, int frame, int tile, const std::string& bytes) {
  if (!job_dirs_.count(job)) {
    std::error_code ec;
    fs::create_directories(root_ / job, ec);
    if (ec) throw std::runtime_error("cannot create " + (root_ / job).string() + ": " + ec.message());
    job_dirs_.insert(job);
  }
  // Written in place, no temp file + rename: a file is only ever *trusted* once the JobStore has
  // synced it and then committed its "done" row, and a file without a committed row is an orphan
  // that load() deletes. So a torn file can exist only where nothing points at it; skipping the
  // rename saves a directory operation per tile (see docs/reliability.md, crash windows).
  const fs::path file = path(job, frame, tile);
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create", file, errno);
  size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      ::unlink(file.c_str());
      fail("cannot write", file, err);
    }
    off += size_t(n);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(file.c_str());
    fail("cannot write", file, err);
  }
}

void TileStore::sync() {
  // One syncfs per batch: file contents, new files and new job directories at once.
  if (::syncfs(root_fd_) != 0) fail("cannot sync", root_, errno);
}

std::optional<std::string> TileStore::read(const std::string& job, int frame, int tile) const {
  std::ifstream in(path(job, frame, tile), std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream ss;
  ss << in.rdbuf();
  if (!in.good() && !in.eof()) return std::nullopt;
  return ss.str();
}

void TileStore::remove(const std::string& job, int frame, int tile) {
  ::unlink(path(job, frame, tile).c_str());  // ENOENT is fine: removal is idempotent
}

void TileStore::remove_job(const std::string& job) {
  std::error_code ec;
  fs::remove_all(root_ / job, ec);
  job_dirs_.erase(job);
}

}  // namespace tessera::server

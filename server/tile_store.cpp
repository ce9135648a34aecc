#include "tile_store.h"

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace tessera::server {

namespace fs = std::filesystem;

namespace {

// Record header, little-endian u32s: magic, payload length, CRC-32 of the payload.
constexpr uint32_t kRecordMagic = 0x54524543;  // "TREC"
constexpr size_t kHeaderSize = 12;

[[noreturn]] void fail(const std::string& what, const fs::path& p, int err) {
  throw std::runtime_error(what + " " + p.string() + ": " + std::strerror(err));
}

void put_u32(std::string& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(char((v >> (8 * i)) & 0xff));
}

uint32_t get_u32(const char* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= uint32_t(uint8_t(p[i])) << (8 * i);
  return v;
}

}  // namespace

uint32_t crc32_ieee(const void* data, size_t size) {
  // crc32_z: a size_t length (crc32() takes 32 bits).
  return uint32_t(::crc32_z(0, static_cast<const Bytef*>(data), size));
}

TileStore::TileStore(fs::path root) : root_(std::move(root)) {
  std::error_code ec;
  fs::create_directories(root_, ec);
  if (ec) throw std::runtime_error("cannot create the tile directory " + root_.string() + ": " + ec.message());
  root_fd_ = ::open(root_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (root_fd_ < 0) fail("cannot open the tile directory", root_, errno);
  for (const auto& e : fs::directory_iterator(root_, ec)) {
    if (auto n = parse_segment_name(e.path().filename().string())) reserve_above(*n);
  }
}

TileStore::~TileStore() {
  if (root_fd_ >= 0) ::close(root_fd_);
}

fs::path TileStore::segment_path(int64_t segment) const { return root_ / (std::to_string(segment) + ".seg"); }

std::optional<int64_t> TileStore::parse_segment_name(const std::string& name) {
  if (name.size() < 5 || name.size() > 24 || name.compare(name.size() - 4, 4, ".seg") != 0) return std::nullopt;
  int64_t n = 0;
  for (size_t i = 0; i + 4 < name.size(); ++i) {
    if (name[i] < '0' || name[i] > '9') return std::nullopt;
    n = n * 10 + (name[i] - '0');
  }
  return n;
}

void TileStore::reserve_above(int64_t n) { next_segment_ = std::max(next_segment_, n + 1); }

std::vector<TileStore::Location> TileStore::write_segment(const std::vector<const std::string*>& payloads) {
  const int64_t segment = next_segment_++;  // never reused, even when this write fails
  const fs::path file = segment_path(segment);
  std::vector<Location> at;
  at.reserve(payloads.size());
  size_t total = 0;
  for (const std::string* p : payloads) total += kHeaderSize + p->size();
  std::string buf;
  buf.reserve(total);
  for (const std::string* p : payloads) {
    at.push_back({segment, int64_t(buf.size()), int64_t(p->size())});
    put_u32(buf, kRecordMagic);
    put_u32(buf, uint32_t(p->size()));
    put_u32(buf, crc32_ieee(p->data(), p->size()));
    buf += *p;
  }
  // A new file each batch, no temp file + rename: a segment is only ever *trusted* once it was
  // synced and then the rows pointing into it were committed; a segment without such rows is
  // an orphan that JobStore::load() deletes (see docs/reliability.md, crash windows).
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create", file, errno);
  auto bail = [&](const char* what, int err) {
    ::close(fd);
    ::unlink(file.c_str());
    fail(what, file, err);
  };
  size_t off = 0;
  while (off < buf.size()) {
    const ssize_t n = ::write(fd, buf.data() + off, buf.size() - off);
    if (n < 0) {
      if (errno == EINTR) continue;
      bail("cannot write", errno);
    }
    off += size_t(n);
  }
  // The file's data (and its size), then its directory entry: both before any row points here.
  if (::fdatasync(fd) != 0) bail("cannot sync", errno);
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(file.c_str());
    fail("cannot write", file, err);
  }
  if (::fsync(root_fd_) != 0) {
    const int err = errno;
    ::unlink(file.c_str());
    fail("cannot sync the directory of", file, err);
  }
  return at;
}

TileStore::ReadResult TileStore::read(const Location& at) const {
  const fs::path file = segment_path(at.segment);
  const std::string where = file.string() + " at offset " + std::to_string(at.offset);
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return {std::nullopt, "cannot open " + file.string() + ": " + std::strerror(errno)};
  auto read_exact = [&](char* dst, size_t n, int64_t pos) {
    size_t got = 0;
    while (got < n) {
      const ssize_t r = ::pread(fd, dst + got, n - got, off_t(pos + int64_t(got)));
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) return false;
      got += size_t(r);
    }
    return true;
  };
  char header[kHeaderSize];
  ReadResult out;
  if (at.offset < 0 || at.length < 0 || !read_exact(header, kHeaderSize, at.offset)) {
    out.error = where + ": the record header is missing (file too short)";
  } else if (get_u32(header) != kRecordMagic) {
    out.error = where + ": no tile record starts here (bad magic)";
  } else if (int64_t(get_u32(header + 4)) != at.length) {
    out.error = where + ": the record holds " + std::to_string(get_u32(header + 4)) + " bytes, the database says " +
                std::to_string(at.length);
  } else {
    std::string bytes(size_t(at.length), '\0');
    if (!read_exact(bytes.data(), bytes.size(), at.offset + int64_t(kHeaderSize))) {
      out.error = where + ": the record is cut short (file too short)";
    } else if (crc32_ieee(bytes.data(), bytes.size()) != get_u32(header + 8)) {
      out.error = where + ": checksum error (CRC-32 mismatch): the tile's bytes are damaged";
    } else {
      out.bytes = std::move(bytes);
    }
  }
  ::close(fd);
  return out;
}

void TileStore::remove_segment(int64_t segment) { ::unlink(segment_path(segment).c_str()); }

}  // namespace tessera::server

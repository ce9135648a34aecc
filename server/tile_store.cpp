// SPDX-License-Identifier: Apache-2.0
#include "tile_store.h"

#include <fcntl.h>
#include <limits.h>
#include <sys/uio.h>
#include <unistd.h>
#include <xxhash.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace tessera::server {

namespace fs = std::filesystem;

namespace {

// Record headers, little-endian. Written: magic "TRX3", payload length (u32), XXH3-64 of the
// payload (u64): 16 bytes. Read as well: the first format, magic "TREC", length, CRC-32 of the
// payload (12 bytes), so segments written before the change stay readable. XXH3 checks a 20 KiB
// tile in about a microsecond; zlib's CRC-32 took several, a tenth of the coordinator's own work
// per tile (docs/performance.md, "The coordinator's cost per tile").
constexpr uint32_t kRecordMagic = 0x33585254;     // "TRX3"
constexpr size_t kHeaderSize = 16;
constexpr uint32_t kCrcRecordMagic = 0x54524543;  // "TREC"
constexpr size_t kCrcHeaderSize = 12;

[[noreturn]] void fail(const std::string& what, const fs::path& p, int err) {
  throw std::runtime_error(what + " " + p.string() + ": " + std::strerror(err));
}

void put_u32(char* out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out[i] = char((v >> (8 * i)) & 0xff);
}

// Writes every byte the iovecs name, in as many writev calls as it takes (IOV_MAX at most each;
// a call may write less than asked). Returns 0 or the errno of the failed call.
int write_all(int fd, std::vector<iovec>& iov) {
  size_t first = 0;
  while (first < iov.size()) {
    const int count = int(std::min<size_t>(iov.size() - first, IOV_MAX));
    const ssize_t n = ::writev(fd, iov.data() + first, count);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (n == 0) return EIO;  // no progress: never expected of a file, and it must not spin
    size_t left = size_t(n);
    while (first < iov.size() && left >= iov[first].iov_len) left -= iov[first++].iov_len;
    if (left > 0) {  // part of one iovec went: the rest of it is next
      iov[first].iov_base = static_cast<char*>(iov[first].iov_base) + left;
      iov[first].iov_len -= left;
    }
  }
  return 0;
}

uint32_t get_u32(const char* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= uint32_t(uint8_t(p[i])) << (8 * i);
  return v;
}

uint64_t get_u64(const char* p) { return uint64_t(get_u32(p)) | uint64_t(get_u32(p + 4)) << 32; }

}  // namespace

uint64_t xxh3_64(const void* data, size_t size) { return XXH3_64bits(data, size); }

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
  close_open();
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

std::vector<TileStore::Location> TileStore::append(const std::vector<const std::string*>& payloads) {
  size_t total = 0;
  for (const std::string* p : payloads) total += kHeaderSize + p->size();
  if (open_.fd >= 0 && open_.size > 0 && open_.size + int64_t(total) > kSegmentBytes) close_open();
  const bool created = open_.fd < 0;
  if (created) {
    const int64_t segment = next_segment_++;  // never reused, even when this write fails
    const fs::path file = segment_path(segment);
    // O_EXCL: a number is never reused, so the file cannot exist unless something else wrote it.
    const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) fail("cannot create", file, errno);
    open_ = {segment, fd, 0};
  }
  last_ = {open_.segment, open_.size, created};
  // The records go straight from the tiles' own bytes (writev): no copy of a batch that, at a
  // second's commit window and thousands of tiles a second, is tens of megabytes.
  std::vector<Location> at;
  at.reserve(payloads.size());
  std::vector<std::array<char, kHeaderSize>> headers(payloads.size());
  std::vector<iovec> iov;
  iov.reserve(2 * payloads.size());
  int64_t offset = open_.size;
  for (size_t i = 0; i < payloads.size(); ++i) {
    const std::string& p = *payloads[i];
    at.push_back({open_.segment, offset, int64_t(p.size())});
    const uint64_t hash = xxh3_64(p.data(), p.size());
    char* h = headers[i].data();
    put_u32(h, kRecordMagic);
    put_u32(h + 4, uint32_t(p.size()));
    put_u32(h + 8, uint32_t(hash));
    put_u32(h + 12, uint32_t(hash >> 32));
    iov.push_back({h, kHeaderSize});
    if (!p.empty()) iov.push_back({const_cast<char*>(p.data()), p.size()});
    offset += int64_t(kHeaderSize + p.size());
  }
  const fs::path file = segment_path(open_.segment);
  auto bail = [&](const char* what, int err) {
    undo_last_append();
    fail(what, file, err);
  };
  if (const int err = write_all(open_.fd, iov); err != 0) bail("cannot write", err);
  open_.size = offset;
  // The file's data (and its size), then, for a new file, its directory entry: both before any
  // row points here.
  if (::fdatasync(open_.fd) != 0) bail("cannot sync", errno);
  if (created && ::fsync(root_fd_) != 0) bail("cannot sync the directory of", errno);
  return at;
}

void TileStore::undo_last_append() {
  if (last_.segment == 0) return;
  if (last_.created) {
    remove_segment(last_.segment);  // closes it
  } else if (open_.segment == last_.segment) {
    if (::ftruncate(open_.fd, off_t(last_.size_before)) == 0) {
      open_.size = last_.size_before;
    } else {
      close_open();  // the tail stays, dead; nothing is appended after it
    }
  }
  last_ = {};
}

void TileStore::close_open() {
  if (open_.fd >= 0) ::close(open_.fd);
  open_ = {};
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
  // The shorter header first: a record of either format starts with it.
  const bool have_header = at.offset >= 0 && at.length >= 0 && read_exact(header, kCrcHeaderSize, at.offset);
  const uint32_t magic = have_header ? get_u32(header) : 0;
  const size_t header_size = magic == kCrcRecordMagic ? kCrcHeaderSize : kHeaderSize;
  if (!have_header || (magic == kRecordMagic && !read_exact(header + kCrcHeaderSize, kHeaderSize - kCrcHeaderSize,
                                                            at.offset + int64_t(kCrcHeaderSize)))) {
    out.error = where + ": the record header is missing (file too short)";
  } else if (magic != kRecordMagic && magic != kCrcRecordMagic) {
    out.error = where + ": no tile record starts here (bad magic)";
  } else if (int64_t(get_u32(header + 4)) != at.length) {
    out.error = where + ": the record holds " + std::to_string(get_u32(header + 4)) + " bytes, the database says " +
                std::to_string(at.length);
  } else {
    std::string bytes(size_t(at.length), '\0');
    if (!read_exact(bytes.data(), bytes.size(), at.offset + int64_t(header_size))) {
      out.error = where + ": the record is cut short (file too short)";
    } else if (magic == kRecordMagic ? xxh3_64(bytes.data(), bytes.size()) != get_u64(header + 8)
                                     : crc32_ieee(bytes.data(), bytes.size()) != get_u32(header + 8)) {
      out.error = where + ": checksum error (" + (magic == kRecordMagic ? "XXH3-64" : "CRC-32") +
                  " mismatch): the tile's bytes are damaged";
    } else {
      out.bytes = std::move(bytes);
    }
  }
  ::close(fd);
  return out;
}

void TileStore::remove_segment(int64_t segment) {
  if (segment == open_.segment) close_open();
  ::unlink(segment_path(segment).c_str());
}

}  // namespace tessera::server

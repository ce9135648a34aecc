// Finished tiles on disk, in segment files: <root>/<n>.seg, one per write batch, holding that
// batch's tiles (the serialized TileData exactly as the coordinator streams it to clients) as
// records, each with a header (magic, length, CRC-32 of the bytes). The database row of a tile
// holds its segment, offset and length.
//
// Crash safety comes from the order the JobStore keeps: write the batch's segment (one create,
// one write), fdatasync it and fsync the directory (the file is new), and only then commit the
// "tile done" rows. So a done row never points at a torn or missing record; a segment no
// committed row still needs (a crash before the commit, or after its last frame was
// acknowledged but before the unlink) is an orphan, deleted at the next start.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace tessera::server {

class TileStore {
 public:
  // Where a tile's bytes are: its record starts at `offset` in segment `segment`; `length` is
  // the payload's size (the header says it too, and the two must agree).
  struct Location {
    int64_t segment = 0;
    int64_t offset = 0;
    int64_t length = 0;
  };

  // Creates the directory; throws std::runtime_error naming it when that fails. New segments are
  // numbered above every *.seg file already there.
  explicit TileStore(std::filesystem::path root);
  ~TileStore();
  TileStore(const TileStore&) = delete;
  TileStore& operator=(const TileStore&) = delete;

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path segment_path(int64_t segment) const;
  // The segment number of a file name "<n>.seg", or nullopt for any other name.
  static std::optional<int64_t> parse_segment_name(const std::string& name);

  // New segments get numbers above `n` too (the database's highest, so a number a row ever held
  // is never used again, even after its file was deleted).
  void reserve_above(int64_t n);

  // Writes one new segment holding `payloads` in order, fdatasyncs it and fsyncs the directory:
  // when this returns the bytes are durable. Returns each payload's location. Throws
  // std::runtime_error with the path and errno text (ENOSPC: "No space left on device"); the
  // partial file is removed.
  std::vector<Location> write_segment(const std::vector<const std::string*>& payloads);

  // The tile's bytes, or an error naming the segment file and what is wrong with the record
  // (missing file, short read, bad magic, length or CRC mismatch).
  struct ReadResult {
    std::optional<std::string> bytes;
    std::string error;
  };
  ReadResult read(const Location& at) const;

  void remove_segment(int64_t segment);  // ENOENT is fine: removal is idempotent

 private:
  std::filesystem::path root_;
  int root_fd_ = -1;
  int64_t next_segment_ = 1;
};

// CRC-32 (IEEE 802.3, the polynomial zlib and PNG use) of `data`, computed by zlib. Every tile
// record on disk holds one: a different checksum would make every stored tile unreadable.
uint32_t crc32_ieee(const void* data, size_t size);

}  // namespace tessera::server

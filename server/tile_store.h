// SPDX-License-Identifier: Apache-2.0
// Finished tiles on disk, in segment files: <root>/<n>.seg, holding tiles (the serialized
// TileData exactly as the coordinator streams it to clients) as records, each with a header
// (magic, length, XXH3-64 of the bytes; records written before carry a CRC-32 and are still
// read). The database row of a tile holds its segment, offset and
// length. Write batches append to one open segment until it holds kSegmentBytes; then the next
// batch starts a new one. (A file per batch cost a create, a directory fsync and later an unlink
// per batch: most of the coordinator's CPU per tile when batches hold a tile or two.)
//
// Crash safety comes from the order the JobStore keeps: append the batch's records (one write),
// fdatasync the segment (and fsync the directory when the batch created the file), and only then
// commit the "tile done" rows. So a done row never points at a torn or missing record. Bytes an
// append left that no committed row points at (a crash before the commit) are dead: never read,
// gone with their segment; a segment no committed row still needs (created by such a batch, or
// emptied by acknowledgements before its unlink) is an orphan, deleted at the next start.
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

  // A segment takes appends until it holds this many bytes (a batch is never split: one larger
  // than this gets a segment to itself).
  static constexpr int64_t kSegmentBytes = int64_t(64) << 20;

  // Appends `payloads` in order to the open segment (a new one when none is open or the open one
  // is full), fdatasyncs it, and fsyncs the directory when the file is new: when this returns the
  // bytes are durable. Returns each payload's location. Throws std::runtime_error with the path
  // and errno text (ENOSPC: "No space left on device"); the segment is then cut back to where it
  // was (removed, if this append created it).
  std::vector<Location> append(const std::vector<const std::string*>& payloads);
  // Takes back the last append (the rows pointing at it were not committed): the segment is cut
  // back to its size before, or removed if that append created it. Best effort: bytes it cannot
  // cut are dead (never pointed at) and the segment is closed to further appends.
  void undo_last_append();
  // The segment appends go to, 0 when none is open.
  int64_t open_segment() const { return open_.segment; }

  // The tile's bytes, or an error naming the segment file and what is wrong with the record
  // (missing file, short read, bad magic, length or checksum mismatch).
  struct ReadResult {
    std::optional<std::string> bytes;
    std::string error;
  };
  ReadResult read(const Location& at) const;

  // ENOENT is fine: removal is idempotent. Removing the open segment closes it.
  void remove_segment(int64_t segment);

 private:
  void close_open();

  struct Open {
    int64_t segment = 0;  // 0: none
    int fd = -1;
    int64_t size = 0;
  };
  struct LastAppend {
    int64_t segment = 0;
    int64_t size_before = 0;
    bool created = false;
  };
  std::filesystem::path root_;
  Open open_;
  LastAppend last_;
  int root_fd_ = -1;
  int64_t next_segment_ = 1;
};

// XXH3-64 of `data` (libxxhash, seed 0): what a tile record written now carries. A different
// hash would make every stored tile unreadable.
uint64_t xxh3_64(const void* data, size_t size);
// CRC-32 (IEEE 802.3, the polynomial zlib and PNG use) of `data`, computed by zlib: what records
// of the first format carry (still read).
uint32_t crc32_ieee(const void* data, size_t size);

}  // namespace tessera::server

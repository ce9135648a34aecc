// Finished tiles on disk: one file per tile, <root>/<job>/<frame>-<tile>.tile, holding the
// serialized TileData exactly as the coordinator streams it to clients.
//
// Crash safety comes from the order the JobStore keeps, not from the file names: write the
// batch's files, sync() (one syncfs of the tile directory's file system: file data and directory
// entries of the whole batch at once, instead of fsync per file and per directory), and only
// then commit the "tile done" rows. So a done row never points at a torn or missing file; a file
// without a row (a crash before the commit) is an orphan, deleted at the next start.
#pragma once

#include <filesystem>
#include <optional>
#include <set>
#include <string>

namespace tessera::server {

class TileStore {
 public:
  // Creates the directory; throws std::runtime_error naming it when that fails.
  explicit TileStore(std::filesystem::path root);
  ~TileStore();
  TileStore(const TileStore&) = delete;
  TileStore& operator=(const TileStore&) = delete;

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path path(const std::string& job, int frame, int tile) const;

  // Writes (or overwrites) the tile's file. Throws std::runtime_error with the path and errno text
  // (ENOSPC: "No space left on device").
  void write(const std::string& job, int frame, int tile, const std::string& bytes);
  // Makes everything written so far durable. Throws on failure.
  void sync();
  std::optional<std::string> read(const std::string& job, int frame, int tile) const;
  void remove(const std::string& job, int frame, int tile);
  void remove_job(const std::string& job);

 private:
  std::filesystem::path root_;
  int root_fd_ = -1;
  std::set<std::string> job_dirs_;  // created this run
};

}  // namespace tessera::server

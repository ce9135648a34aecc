// SPDX-License-Identifier: Apache-2.0
// Content-addressed storage of scene bundles under <data-dir>/bundles: <sha256>.bundle holds the
// bytes as uploaded (what workers fetch), <sha256>/ the extracted files (what the coordinator
// parses to validate a job). Writes are atomic (temporary file + rename), so a crash never
// leaves a bundle that looks complete but is not; uploads in progress (.upload-*) left by a
// crash are removed at start.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>

namespace tessera::server {

class BundleStore {
 public:
  explicit BundleStore(std::filesystem::path data_dir);

  bool has(const std::string& sha256) const;
  // Checks that `bytes` hash to `sha256` and form a valid bundle, then stores and extracts it.
  // Throws farm::BundleError naming the problem. Storing a bundle twice is harmless.
  void put(const std::string& sha256, const std::string& bytes);
  // The same for an upload already on disk (bundle_upload.h), whose bytes the caller found to
  // hash to `sha256`: read back, validated, extracted and renamed into place, one bundle at a
  // time (so validation holds at most one bundle in memory). Throws farm::BundleError.
  void put_file(const std::string& sha256, const std::filesystem::path& uploaded);
  std::optional<std::string> read(const std::string& sha256) const;
  // The scene file of a stored bundle (extracted on demand).
  std::filesystem::path scene_path(const std::string& sha256);
  const std::filesystem::path& dir() const { return dir_; }
  // Since start: bytes of new bundles stored, and bytes read back for workers (metrics).
  uint64_t bytes_stored() const { return bytes_stored_.load(std::memory_order_relaxed); }
  uint64_t bytes_served() const { return bytes_served_.load(std::memory_order_relaxed); }

 private:
  std::filesystem::path file_of(const std::string& sha256) const { return dir_ / (sha256 + ".bundle"); }
  std::filesystem::path dir_;
  mutable std::atomic<uint64_t> bytes_stored_{0}, bytes_served_{0};
  std::mutex mu_;  // serializes extraction of the same bundle by concurrent submits
};

}  // namespace tessera::server

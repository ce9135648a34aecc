// SPDX-License-Identifier: Apache-2.0
// Scene bundles: the scene file plus every file it reads, as one tessera.v1.Bundle message,
// identified by the SHA-256 of its serialized bytes. Shared by the client (builds and uploads),
// the coordinator (stores, validates) and the worker (fetches, caches).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "farm/farm_error.h"

namespace tessera::v1 {
class Bundle;
}

namespace tessera::farm {

class BundleError : public FarmError {
 public:
  using FarmError::FarmError;
};

std::string sha256_hex(std::string_view bytes);
bool is_sha256_hex(std::string_view s);

struct BuiltBundle {
  std::string bytes;       // serialized tessera.v1.Bundle
  std::string sha256;      // of `bytes`
  std::string scene_file;  // path of the scene inside the bundle
  size_t files = 0;
};

// Reads the scene file and its dependencies (relative to the scene's directory). Paths inside
// the bundle are relative to the deepest directory containing all of them, so dependencies that
// climb out of the scene's directory ("../models/x.obj") still fit. Throws BundleError.
BuiltBundle make_bundle(const std::filesystem::path& scene_file, const std::vector<std::string>& dependencies);

// Checks a bundle path: relative, no "..", no empty or "." components.
bool is_safe_bundle_path(std::string_view path);

// Parses and validates bundle bytes without touching the disk: every path safe, no entry twice,
// no entry that is also another entry's directory ("a" and "a/b"), the scene file present.
// Throws BundleError naming the entry.
void parse_bundle(std::string_view bytes, tessera::v1::Bundle* out);

// Parses (parse_bundle) and writes the bundle's files under `dir` (created; written to a temporary sibling and
// renamed, so a crash never leaves a half-written directory). Returns the scene file's path.
// Throws BundleError on malformed bytes or unsafe paths.
std::filesystem::path extract_bundle(std::string_view bytes, const std::filesystem::path& dir);
// The scene file's path in an already extracted bundle directory.
std::filesystem::path extracted_scene_path(const std::filesystem::path& dir);

}  // namespace tessera::farm

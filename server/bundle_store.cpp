// SPDX-License-Identifier: Apache-2.0
#include "bundle_store.h"

#include <fstream>
#include <sstream>
#include <vector>

#include "farm/bundle.h"
#include "farm/temp_file.h"

namespace tessera::server {

namespace fs = std::filesystem;
using farm::BundleError;

BundleStore::BundleStore(fs::path data_dir) : dir_(std::move(data_dir) / "bundles") {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw BundleError("cannot create bundle store " + dir_.string() + ": " + ec.message());
  // Uploads in progress when the coordinator died (bundle_upload.h) will never finish.
  std::vector<fs::path> stale;
  for (const auto& e : fs::directory_iterator(dir_, ec)) {
    if (e.path().filename().string().rfind(".upload-", 0) == 0) stale.push_back(e.path());
  }
  for (const auto& p : stale) fs::remove(p, ec);
}

bool BundleStore::has(const std::string& sha256) const {
  return farm::is_sha256_hex(sha256) && fs::exists(file_of(sha256));
}

void BundleStore::put(const std::string& sha256, const std::string& bytes) {
  if (!farm::is_sha256_hex(sha256)) throw BundleError("'" + sha256 + "' is not a lower-case hex SHA-256");
  const std::string actual = farm::sha256_hex(bytes);
  if (actual != sha256) {
    throw BundleError("bundle bytes hash to " + actual + ", not to the announced " + sha256);
  }
  std::lock_guard lock(mu_);
  farm::extract_bundle(bytes, dir_ / sha256);  // validates structure and paths
  if (fs::exists(file_of(sha256))) return;
  const fs::path tmp = farm::make_temp_file(dir_, sha256 + ".tmp");
  {
    std::ofstream out(tmp, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw BundleError("cannot write " + tmp.string() + " (disk full?)");
    }
  }
  fs::rename(tmp, file_of(sha256));
  bytes_stored_ += bytes.size();
}

void BundleStore::put_file(const std::string& sha256, const fs::path& uploaded) {
  if (!farm::is_sha256_hex(sha256)) throw BundleError("'" + sha256 + "' is not a lower-case hex SHA-256");
  std::lock_guard lock(mu_);
  std::string bytes;
  {
    std::ifstream in(uploaded, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    if (!in && !in.eof()) throw BundleError("cannot read the upload " + uploaded.string());
    bytes = ss.str();
  }
  farm::extract_bundle(bytes, dir_ / sha256);  // validates structure and paths
  if (fs::exists(file_of(sha256))) return;
  fs::rename(uploaded, file_of(sha256));
  bytes_stored_ += bytes.size();
}

std::optional<std::string> BundleStore::read(const std::string& sha256) const {
  if (!has(sha256)) return std::nullopt;
  std::ifstream in(file_of(sha256), std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream ss;
  ss << in.rdbuf();
  std::string bytes = ss.str();
  bytes_served_ += bytes.size();
  return bytes;
}

fs::path BundleStore::scene_path(const std::string& sha256) {
  const fs::path dir = dir_ / sha256;
  fs::path p = farm::extracted_scene_path(dir);
  if (fs::exists(p)) return p;
  auto bytes = read(sha256);
  if (!bytes) throw BundleError("bundle " + sha256 + " is not stored");
  std::lock_guard lock(mu_);
  return farm::extract_bundle(*bytes, dir);
}

}  // namespace tessera::server

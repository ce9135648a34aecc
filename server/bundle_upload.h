// SPDX-License-Identifier: Apache-2.0
// One bundle upload in progress: its bytes go to a temporary file in the bundle store while
// their SHA-256 is computed, so an upload costs the coordinator one chunk of memory however
// large the bundle is (they used to be buffered whole: four concurrent 300 MB uploads took it to
// 1.7 GB before each was refused for a wrong hash). Only a bundle whose bytes
// hash to what was announced is read back, validated and stored (BundleStore::put_file, one at
// a time). UploadSlots bounds how many uploads run at once.
#pragma once

#include <grpcpp/grpcpp.h>
#include <openssl/evp.h>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>

namespace tessera::server {

class BundleUpload {
 public:
  explicit BundleUpload(const std::filesystem::path& store_dir);  // throws std::runtime_error
  ~BundleUpload();  // removes the temporary file unless it was taken
  BundleUpload(const BundleUpload&) = delete;
  BundleUpload& operator=(const BundleUpload&) = delete;

  void append(const std::string& data);  // throws std::runtime_error (disk full...)
  int64_t size() const { return size_; }
  // Closes the file; the lower-case hex SHA-256 of everything appended.
  std::string finish();
  const std::filesystem::path& path() const { return path_; }
  void taken() { taken_ = true; }  // the store renamed the file: do not remove it

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  EVP_MD_CTX* md_ = nullptr;
  int64_t size_ = 0;
  bool taken_ = false;
};

// How many uploads may run at once (--max-concurrent-uploads).
class UploadSlots {
 public:
  explicit UploadSlots(int max) : max_(max) {}
  // OK and a slot taken, or RESOURCE_EXHAUSTED naming the limit.
  grpc::Status acquire();
  void release() { --active_; }

 private:
  int max_;
  std::atomic<int> active_{0};
};

}  // namespace tessera::server

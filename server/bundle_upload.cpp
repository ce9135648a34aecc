// SPDX-License-Identifier: Apache-2.0
#include "bundle_upload.h"

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "farm/request_limits.h"

namespace tessera::server {

BundleUpload::BundleUpload(const std::filesystem::path& store_dir) {
  // A name of mkstemp's making; the ".upload-" prefix is what BundleStore removes at start (an
  // upload a crash cut short never finishes).
  std::string name = (store_dir / ".upload-XXXXXX").string();
  fd_ = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd_ < 0) throw std::runtime_error("cannot create " + name + ": " + std::strerror(errno));
  path_ = name;
  md_ = EVP_MD_CTX_new();
  if (!md_ || EVP_DigestInit_ex(md_, EVP_sha256(), nullptr) != 1) throw std::runtime_error("SHA-256 failed (OpenSSL)");
}

BundleUpload::~BundleUpload() {
  if (fd_ >= 0) ::close(fd_);
  if (md_) EVP_MD_CTX_free(md_);
  if (!taken_) ::unlink(path_.c_str());
}

void BundleUpload::append(const std::string& data) {
  EVP_DigestUpdate(md_, data.data(), data.size());
  size_t off = 0;
  while (off < data.size()) {
    const ssize_t n = ::write(fd_, data.data() + off, data.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw std::runtime_error("cannot write " + path_.string() + ": " + std::strerror(errno));
    off += size_t(n);
  }
  size_ += int64_t(data.size());
}

std::string BundleUpload::finish() {
  unsigned char d[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_DigestFinal_ex(md_, d, &len);
  if (::close(fd_) != 0) {
    fd_ = -1;
    throw std::runtime_error("cannot write " + path_.string() + ": " + std::strerror(errno));
  }
  fd_ = -1;
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (unsigned i = 0; i < len; ++i) {
    out.push_back(hex[d[i] >> 4]);
    out.push_back(hex[d[i] & 15]);
  }
  return out;
}

grpc::Status UploadSlots::acquire() {
  const int n = ++active_;
  if (n <= max_) return grpc::Status::OK;
  --active_;
  return farm::over_limit(grpc::StatusCode::RESOURCE_EXHAUSTED, "the number of bundle uploads in progress", n,
                    "--max-concurrent-uploads", max_);
}

}  // namespace tessera::server

#include "bundle_upload.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>
#include <stdexcept>

#include "farm/request_limits.h"

namespace tessera::server {

BundleUpload::BundleUpload(const std::filesystem::path& store_dir) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  path_ = store_dir / (".upload-" + std::to_string(rng()));
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) throw std::runtime_error("cannot create " + path_.string() + ": " + std::strerror(errno));
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

// SPDX-License-Identifier: Apache-2.0
#include "bundle_upload.h"

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <sstream>
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

namespace {

std::string seconds_text(std::chrono::milliseconds t) {
  std::ostringstream s;
  s << double(t.count()) / 1000.0 << " s";
  return s.str();
}

}  // namespace

UploadSlots::UploadSlots(int max, std::chrono::milliseconds idle_timeout)
    : max_(max), idle_timeout_(idle_timeout), watchdog_([this] { watch(); }) {}

UploadSlots::~UploadSlots() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  watchdog_.join();
}

grpc::Status UploadSlots::acquire() {
  const int n = ++active_;
  if (n <= max_) return grpc::Status::OK;
  --active_;
  const grpc::Status over = farm::over_limit(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                             "the number of bundle uploads in progress", n, "--max-concurrent-uploads",
                                             max_);
  return grpc::Status(over.error_code(), over.error_message() + "; an upload that sends nothing for " +
                                             seconds_text(idle_timeout_) + " is ended (--upload-idle-seconds)");
}

void UploadSlots::waiting(Waiter* upload, bool waiting) {
  std::lock_guard lock(mu_);
  if (waiting) {
    waiting_[upload] = std::chrono::steady_clock::now();
  } else {
    waiting_.erase(upload);
  }
}

void UploadSlots::release(Waiter* upload) {
  {
    std::lock_guard lock(mu_);  // the watchdog tells under it: not telling `upload` once we hold it
    waiting_.erase(upload);
  }
  --active_;
}

grpc::Status UploadSlots::idle_status() const {
  return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED,
                      "the bundle upload sent no chunk for " + seconds_text(idle_timeout_) +
                          ", this coordinator's limit (tessera-server --upload-idle-seconds): nothing of it was "
                          "kept; upload it again");
}

void UploadSlots::watch() {
  const auto tick = std::clamp(idle_timeout_ / 4, std::chrono::milliseconds(10), std::chrono::milliseconds(1000));
  std::unique_lock lock(mu_);
  while (!cv_.wait_for(lock, tick, [this] { return stop_; })) {
    const auto now = std::chrono::steady_clock::now();
    for (auto it = waiting_.begin(); it != waiting_.end();) {
      if (now - it->second < idle_timeout_) {
        ++it;
        continue;
      }
      Waiter* upload = it->first;
      it = waiting_.erase(it);  // told once
      upload->idle_too_long();
    }
  }
}

}  // namespace tessera::server

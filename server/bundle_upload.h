// SPDX-License-Identifier: Apache-2.0
// One bundle upload in progress: its bytes go to a temporary file in the bundle store while
// their SHA-256 is computed, so an upload costs the coordinator one chunk of memory however
// large the bundle is (they used to be buffered whole: four concurrent 300 MB uploads took it to
// 1.7 GB before each was refused for a wrong hash). Only a bundle whose bytes
// hash to what was announced is read back, validated and stored (BundleStore::put_file, one at
// a time). UploadSlots bounds how many uploads run at once, and how long one may stall.
#pragma once

#include <grpcpp/grpcpp.h>
#include <openssl/evp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <thread>

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

// The uploads in progress: how many may run at once (--max-concurrent-uploads), and how long one
// may wait for its next chunk (--upload-idle-seconds). A watchdog thread ends an upload that
// waited longer, so that a client that stalls gives its slot back (four streams that sent 1 MiB
// and stopped used to hold every slot for good, and every new scene was refused).
class UploadSlots {
 public:
  // An upload holding a slot, told once when it has waited too long for a chunk (on the
  // watchdog thread, under the slots' lock: it must only end its call, never call back here).
  class Waiter {
   public:
    virtual void idle_too_long() = 0;

   protected:
    ~Waiter() = default;
  };

  UploadSlots(int max, std::chrono::milliseconds idle_timeout);
  ~UploadSlots();  // stops the watchdog
  UploadSlots(const UploadSlots&) = delete;
  UploadSlots& operator=(const UploadSlots&) = delete;

  // OK and a slot taken, or RESOURCE_EXHAUSTED naming the limit.
  grpc::Status acquire();
  // The upload holding a slot waits for a chunk from now on (true), or has one (false: the
  // clock stops while it writes the chunk, or stores the bundle at the end).
  void waiting(Waiter* upload, bool waiting);
  // Gives the slot back; `upload` is not being told and is never told anything once this returns.
  void release(Waiter* upload);
  // DEADLINE_EXCEEDED naming the timeout and its flag: how an upload that stalled ends.
  grpc::Status idle_status() const;

 private:
  void watch();

  const int max_;
  const std::chrono::milliseconds idle_timeout_;
  std::atomic<int> active_{0};
  std::mutex mu_;
  std::condition_variable cv_;
  std::map<Waiter*, std::chrono::steady_clock::time_point> waiting_;  // since when, under mu_
  bool stop_ = false;
  std::thread watchdog_;
};

}  // namespace tessera::server

// SPDX-License-Identifier: Apache-2.0
// The process's one Embree device (Embree tutorials: one device per process, the error
// callback installed before anything else can fail), with RAII handles for scenes/geometries.
#pragma once

#include <embree3/rtcore.h>

#include <stdexcept>
#include <string>
#include <utility>

namespace tessera {

class EmbreeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Returns the process-wide device, created on first use. Thread-safe.
RTCDevice embree_device();
// Throws EmbreeError if the device recorded an error since the last check.
void check_embree(const char* what);
// Embree's name for the ISA its kernels were selected for (e.g. "AVX512"): results are
// bit-identical only between machines that run the same kernels.
std::string embree_isa();

// Owns one reference to an Embree object; releases it on destruction.
template <typename Handle, void (*Release)(Handle)>
class EmbreeHandle {
 public:
  EmbreeHandle() = default;
  explicit EmbreeHandle(Handle h) : h_(h) {}
  EmbreeHandle(const EmbreeHandle&) = delete;
  EmbreeHandle& operator=(const EmbreeHandle&) = delete;
  EmbreeHandle(EmbreeHandle&& o) noexcept : h_(std::exchange(o.h_, nullptr)) {}
  EmbreeHandle& operator=(EmbreeHandle&& o) noexcept {
    if (this != &o) {
      reset();
      h_ = std::exchange(o.h_, nullptr);
    }
    return *this;
  }
  ~EmbreeHandle() { reset(); }
  void reset() {
    if (h_) Release(h_);
    h_ = nullptr;
  }
  Handle get() const { return h_; }

 private:
  Handle h_ = nullptr;
};

using SceneHandle = EmbreeHandle<RTCScene, rtcReleaseScene>;
using GeometryHandle = EmbreeHandle<RTCGeometry, rtcReleaseGeometry>;

}  // namespace tessera

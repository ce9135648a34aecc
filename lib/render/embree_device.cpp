// SPDX-License-Identifier: Apache-2.0
#include "render/embree_device.h"

#include <spdlog/spdlog.h>

#include <mutex>

namespace tessera {

namespace {

std::mutex g_error_mutex;
std::string g_last_error;

void on_embree_error(void*, RTCError code, const char* message) {
  if (code == RTC_ERROR_NONE) return;
  const char* name = "unknown";
  switch (code) {
    case RTC_ERROR_INVALID_ARGUMENT: name = "invalid argument"; break;
    case RTC_ERROR_INVALID_OPERATION: name = "invalid operation"; break;
    case RTC_ERROR_OUT_OF_MEMORY: name = "out of memory"; break;
    case RTC_ERROR_UNSUPPORTED_CPU: name = "unsupported CPU"; break;
    case RTC_ERROR_CANCELLED: name = "cancelled"; break;
    default: break;
  }
  spdlog::error("embree: {}: {}", name, message ? message : "");
  std::lock_guard lock(g_error_mutex);
  g_last_error = std::string(name) + ": " + (message ? message : "");
}

struct Device {
  RTCDevice device = nullptr;
  Device() {
    // Create with the error callback set as the very first thing (rtcNewDevice's own failure
    // is reported through rtcGetDeviceError(nullptr)).
    device = rtcNewDevice("verbose=0");
    if (!device) {
      throw EmbreeError("cannot create Embree device (error " +
                        std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    }
    rtcSetDeviceErrorFunction(device, on_embree_error, nullptr);
  }
  ~Device() { rtcReleaseDevice(device); }
};

}  // namespace

RTCDevice embree_device() {
  static Device d;
  return d.device;
}

void check_embree(const char* what) {
  std::lock_guard lock(g_error_mutex);
  if (!g_last_error.empty()) {
    std::string e = std::exchange(g_last_error, {});
    throw EmbreeError(std::string(what) + ": embree " + e);
  }
}

std::string embree_isa() {
  // Embree 3 exposes no ISA query; the version plus the CPU's best vector ISA identify the kernels.
  std::string isa = "sse2";
#if defined(__x86_64__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl")) isa = "avx512";
  else if (__builtin_cpu_supports("avx2")) isa = "avx2";
  else if (__builtin_cpu_supports("avx")) isa = "avx";
  else if (__builtin_cpu_supports("sse4.2")) isa = "sse4.2";
#endif
  return "embree-" + std::to_string(rtcGetDeviceProperty(embree_device(), RTC_DEVICE_PROPERTY_VERSION)) + "-" + isa;
}

}  // namespace tessera

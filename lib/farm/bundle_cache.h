// SPDX-License-Identifier: Apache-2.0
// The worker's cache of scenes: bundles on disk by SHA-256 (fetched once, kept across restarts),
// the parsed Scene per (bundle, overrides), and the built RenderScene per (bundle, overrides,
// frame), the expensive part, for the few most recent frames. Thread-safe: render threads that
// need the same frame at once wait for one build instead of building it twice.
#pragma once

#include <filesystem>
#include <functional>
#include <future>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "render/render_scene.h"
#include "scene/scene.h"

namespace tessera::farm {

class BundleCache {
 public:
  // `fetch(sha256)` returns the bundle's bytes (from the coordinator); throws on failure.
  using FetchFn = std::function<std::string(const std::string& sha256)>;

  BundleCache(std::filesystem::path dir, FetchFn fetch, size_t max_frames = 4);

  // `overrides` is the serialized tessera.v1.ImageOverrides of the job.
  std::shared_ptr<const RenderScene> frame(const std::string& sha256, const std::string& overrides, int frame);
  // The parsed scene (fetched and loaded on first use), kept for as long as the cache lives.
  std::shared_ptr<const Scene> scene(const std::string& sha256, const std::string& overrides);

 private:
  std::filesystem::path ensure_extracted(const std::string& sha256);

  std::filesystem::path dir_;
  FetchFn fetch_;
  size_t max_frames_;
  std::mutex mu_;
  std::map<std::string, std::shared_future<std::shared_ptr<const Scene>>> scenes_;
  std::map<std::string, std::shared_future<std::shared_ptr<const RenderScene>>> frames_;
  std::list<std::string> frame_lru_;  // most recent first
  std::mutex fetch_mu_;               // one download at a time
};

}  // namespace tessera::farm

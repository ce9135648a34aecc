// SPDX-License-Identifier: Apache-2.0
// The ray server's scenes: bundles fetched from the coordinator with the worker token and kept
// on disk, parsed scenes and built frames cached exactly as a worker caches them (it is the
// worker's BundleCache), so a scene is loaded once however many queries name it.
#pragma once

#include <filesystem>
#include <memory>

#include "farm/bundle_cache.h"
#include "scene_source.h"

namespace tessera::rayserver {

class BundleScenes {
 public:
  // `fetch` downloads a bundle (farm::fetch_bundle); it throws farm::FetchError.
  BundleScenes(std::filesystem::path cache_dir, farm::BundleCache::FetchFn fetch, size_t max_frames = 8);
  grpc::Status get(const std::string& sha256, int frame, std::shared_ptr<const rays::RayTracer>* tracer);
  SceneSource source() {
    return [this](const std::string& sha256, int frame, std::shared_ptr<const rays::RayTracer>* t) {
      return get(sha256, frame, t);
    };
  }

 private:
  farm::BundleCache cache_;
};

}  // namespace tessera::rayserver

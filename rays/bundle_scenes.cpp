// SPDX-License-Identifier: Apache-2.0
#include "bundle_scenes.h"

#include "farm/bundle.h"
#include "farm/bundle_fetch.h"
#include "scene/scene_parser.h"

namespace tessera::rayserver {

BundleScenes::BundleScenes(std::filesystem::path cache_dir, farm::BundleCache::FetchFn fetch, size_t max_frames)
    : cache_(std::move(cache_dir), std::move(fetch), max_frames) {}

grpc::Status BundleScenes::get(const std::string& sha256, int frame,
                               std::shared_ptr<const rays::RayTracer>* tracer) {
  using grpc::Status;
  using grpc::StatusCode;
  if (!farm::is_sha256_hex(sha256)) {
    return Status(StatusCode::INVALID_ARGUMENT,
                  "scene.bundle_sha256: '" + sha256.substr(0, 80) + "' is not a SHA-256 (64 lowercase hex digits)");
  }
  try {
    // The scene first: its frame count decides whether the frame exists before anything is built.
    std::shared_ptr<const Scene> scene = cache_.scene(sha256, "");
    if (frame < 0 || frame >= scene->frame_count()) {
      return Status(StatusCode::INVALID_ARGUMENT, "scene.frame: " + std::to_string(frame) + " is not a frame of " +
                                                      sha256.substr(0, 12) + " (frames 0-" +
                                                      std::to_string(scene->frame_count() - 1) + ")");
    }
    *tracer = std::make_shared<const rays::RayTracer>(scene, cache_.frame(sha256, "", frame));
    return Status::OK;
  } catch (const farm::FetchError& e) {
    if (e.code() == StatusCode::NOT_FOUND) {
      return Status(StatusCode::INVALID_ARGUMENT, "scene.bundle_sha256: unknown bundle " + sha256 +
                                                      " (the coordinator does not have it: upload it first, "
                                                      "as `tessera rays --server` does)");
    }
    return Status(StatusCode::UNAVAILABLE, std::string("cannot get the scene from the coordinator: ") + e.what());
  } catch (const std::exception& e) {
    return Status(StatusCode::FAILED_PRECONDITION, "scene " + sha256.substr(0, 12) + " does not load: " + e.what());
  }
}

}  // namespace tessera::rayserver

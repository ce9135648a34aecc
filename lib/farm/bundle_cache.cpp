// SPDX-License-Identifier: Apache-2.0
#include "farm/bundle_cache.h"

#include <spdlog/spdlog.h>

#include "farm/bundle.h"
#include "farm/overrides_codec.h"
#include "scene/scene_parser.h"
#include "tessera/v1/common.pb.h"

namespace tessera::farm {

namespace fs = std::filesystem;

BundleCache::BundleCache(fs::path dir, FetchFn fetch, size_t max_frames)
    : dir_(std::move(dir)), fetch_(std::move(fetch)), max_frames_(std::max<size_t>(1, max_frames)) {
  fs::create_directories(dir_);
}

fs::path BundleCache::ensure_extracted(const std::string& sha256) {
  if (!farm::is_sha256_hex(sha256)) throw farm::BundleError("bad bundle hash '" + sha256 + "'");
  const fs::path d = dir_ / sha256;
  fs::path scene = farm::extracted_scene_path(d);
  if (fs::exists(scene)) return scene;
  std::lock_guard lock(fetch_mu_);
  scene = farm::extracted_scene_path(d);
  if (fs::exists(scene)) return scene;
  const std::string bytes = fetch_(sha256);
  if (farm::sha256_hex(bytes) != sha256) throw farm::BundleError("fetched bundle does not hash to " + sha256);
  spdlog::info("bundle {} fetched ({} bytes)", sha256.substr(0, 12), bytes.size());
  return farm::extract_bundle(bytes, d);
}

std::shared_ptr<const Scene> BundleCache::scene(const std::string& sha256, const std::string& overrides) {
  const std::string key = sha256 + '\0' + overrides;
  std::promise<std::shared_ptr<const Scene>> promise;
  std::shared_future<std::shared_ptr<const Scene>> fut;
  bool mine = false;
  {
    std::lock_guard lock(mu_);
    auto it = scenes_.find(key);
    if (it == scenes_.end()) {
      fut = promise.get_future().share();
      scenes_[key] = fut;
      mine = true;
    } else {
      fut = it->second;
    }
  }
  if (mine) {
    try {
      // Exactly what `tessera render` does: load the file, apply the overrides.
      tessera::v1::ImageOverrides o;
      o.ParseFromString(overrides);
      // Confined to the bundle as on the coordinator: a scene from the farm reads nothing else.
      const fs::path scene_path = ensure_extracted(sha256);
      SceneLoadOptions options;
      options.confine_to = (dir_ / sha256).string();  // the bundle's root, as the coordinator's
      options.gltf = farm::gltf_options_from_proto(o);
      auto s = std::make_shared<Scene>(load_scene(scene_path.string(), options));
      apply_overrides(*s, farm::from_proto(o));
      promise.set_value(std::move(s));
    } catch (...) {
      {
        std::lock_guard lock(mu_);
        scenes_.erase(key);  // let a later tile try again (e.g. after a failed download)
      }
      promise.set_exception(std::current_exception());
    }
  }
  return fut.get();
}

std::shared_ptr<const RenderScene> BundleCache::frame(const std::string& sha256, const std::string& overrides,
                                                      int frame) {
  const std::string key = sha256 + '\0' + overrides + '\0' + std::to_string(frame);
  std::promise<std::shared_ptr<const RenderScene>> promise;
  std::shared_future<std::shared_ptr<const RenderScene>> fut;
  bool mine = false;
  {
    std::lock_guard lock(mu_);
    auto it = frames_.find(key);
    frame_lru_.remove(key);
    frame_lru_.push_front(key);
    if (it == frames_.end()) {
      fut = promise.get_future().share();
      frames_[key] = fut;
      mine = true;
      // Evict the least recently used frames; tiles still rendering hold their own reference.
      while (frame_lru_.size() > max_frames_) {
        frames_.erase(frame_lru_.back());
        frame_lru_.pop_back();
      }
    } else {
      fut = it->second;
    }
  }
  if (mine) {
    try {
      auto s = scene(sha256, overrides);
      promise.set_value(make_render_scene(*s, frame));
    } catch (...) {
      {
        std::lock_guard lock(mu_);
        frames_.erase(key);
        frame_lru_.remove(key);
      }
      promise.set_exception(std::current_exception());
    }
  }
  return fut.get();
}

}  // namespace tessera::farm

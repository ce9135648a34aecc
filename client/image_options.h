// The scene overrides shared by `tessera render` and `tessera submit`: one set of flags, one
// validation, so both commands accept and refuse exactly the same values.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "scene/scene_parser.h"

namespace tessera::cli {

struct ImageOptions {
  ImageOverrides overrides;
  std::string sampler;  // empty: the scene's
  GltfOptions gltf;     // --camera, --scene-index, --fps: how a glTF scene file is read
  bool gltf_given() const { return !gltf.camera.empty() || gltf.scene_index >= 0 || gltf.fps != GltfOptions{}.fps; }
};

// Adds --spp, --width, --height, --max-depth, --seed, --sampler, --target-rmse, --min-spp, --max-spp,
// and the glTF options --camera, --scene-index, --fps.
void add_image_options(CLI::App& command, ImageOptions& options);

// Loads the scene and applies the overrides; throws SceneError naming the file or flag.
// `resolved` (optional) receives the overrides with the sampler name parsed, as sent to a farm.
Scene load_scene_with(const std::string& path, const ImageOptions& options, ImageOverrides* resolved = nullptr);

}  // namespace tessera::cli

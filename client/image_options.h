// SPDX-License-Identifier: Apache-2.0
// The scene overrides shared by `tessera render` and `tessera submit`: one set of flags, one
// validation, so both commands accept and refuse exactly the same values.
#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

#include "scene/scene_parser.h"

namespace tessera::cli {

struct ImageOptions {
  ImageOverrides overrides;
  std::string sampler;  // empty: the scene's
  // --camera, --scene-index, --fps: how a glTF scene file is read (optional: a value given on
  // the command line is checked even where it equals the default's meaning).
  std::string camera;
  std::optional<int> scene_index;
  std::optional<double> fps;
  // The glTF options the flags give; throws SceneError naming the flag and its range.
  GltfOptions gltf_options() const;
};

// Adds --spp, --width, --height, --max-depth, --seed, --sampler, --target-rmse, --min-spp, --max-spp,
// and the glTF options --camera, --scene-index, --fps.
void add_image_options(CLI::App& command, ImageOptions& options);

// Loads the scene and applies the overrides; throws SceneError naming the file or flag.
// `resolved` (optional) receives the overrides with the sampler name parsed, as sent to a farm.
Scene load_scene_with(const std::string& path, const ImageOptions& options, ImageOverrides* resolved = nullptr);

}  // namespace tessera::cli

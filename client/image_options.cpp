// SPDX-License-Identifier: Apache-2.0
#include "image_options.h"

#include "scene/gltf_scene.h"

namespace tessera::cli {

void add_image_options(CLI::App& cmd, ImageOptions& o) {
  cmd.add_option("--spp", o.overrides.spp, "Samples per pixel (overrides the scene)");
  cmd.add_option("--width", o.overrides.width, "Image width (overrides the scene)");
  cmd.add_option("--height", o.overrides.height, "Image height (overrides the scene)");
  cmd.add_option("--max-depth", o.overrides.max_depth, "Maximum reflection/refraction depth");
  cmd.add_option("--seed", o.overrides.seed, "Sampler seed");
  cmd.add_option("--roulette-weight", o.overrides.roulette_weight,
                 "Russian roulette on reflection/refraction rays below this path weight, in [0, 1] (default: the "
                 "scene's, 0.01; 0 traces every branch)");
  cmd.add_option("--sampler", o.sampler,
                 "sobol (default; also called stratified), cmj, independent, center, or lattice (with --target-rmse: "
                 "shared pixel corners where the image is smooth, audited; render/lattice_sampler.h)");
  cmd.add_option("--target-rmse", o.overrides.target_rmse,
                 "Render to a target error of the frame: its estimated RMSE (linear light) at most this, samples "
                 "where they pay most");
  cmd.add_option("--block-rmse", o.overrides.block_rmse,
                 "Render to a bound on every 8x8 block's estimated RMSE (linear light): each block takes samples "
                 "until it is at most this");
  cmd.add_option("--min-spp", o.overrides.min_spp,
                 "With --target-rmse or --block-rmse: fewest samples per pixel (default 2 and 16)");
  cmd.add_option("--max-spp", o.overrides.max_spp,
                 "With --target-rmse or --block-rmse: most samples per pixel (default 1024)");
  cmd.add_option("--camera", o.camera, "glTF scenes: the camera to render (camera or node name; default: the first)");
  cmd.add_option("--scene-index", o.scene_index, "glTF scenes: the index in the file's scenes (default: its scene)");
  cmd.add_option("--fps", o.fps, "glTF scenes: animation frames per second, in (0, 1000] (default 24)");
}

GltfOptions ImageOptions::gltf_options() const {
  GltfOptions g;
  g.camera = camera;
  if (scene_index) {
    if (*scene_index < 0) throw SceneError("--scene-index: must be >= 0, got " + std::to_string(*scene_index));
    g.scene_index = *scene_index;
  }
  if (fps) {
    if (!(*fps > 0 && *fps <= GltfOptions::kMaxFps)) {
      throw SceneError("--fps: must be in (0, " + std::to_string(int(GltfOptions::kMaxFps)) + "], got " +
                       std::to_string(*fps));
    }
    g.fps = *fps;
  }
  return g;
}

Scene load_scene_with(const std::string& path, const ImageOptions& o, ImageOverrides* resolved) {
  SceneLoadOptions load;
  load.gltf = o.gltf_options();
  if ((load.gltf.given() || o.scene_index || o.fps) && !is_gltf_path(path)) {
    throw SceneError("--camera, --scene-index and --fps apply to glTF scenes (.gltf, .glb) only");
  }
  Scene scene = load_scene(path, load);
  ImageOverrides overrides = o.overrides;
  if (!o.sampler.empty()) {
    overrides.sampler = sampler_from_name(o.sampler);
    if (!overrides.sampler) {
      throw SceneError("--sampler: must be one of " + std::string(sampler_names()) + ", got '" + o.sampler + "'");
    }
  }
  apply_overrides(scene, overrides);
  if (resolved) *resolved = overrides;
  return scene;
}

}  // namespace tessera::cli

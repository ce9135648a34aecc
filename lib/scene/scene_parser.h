// SPDX-License-Identifier: Apache-2.0
// Reads a scene file (JSON, see docs/scene-format.md) into a Scene, loading its meshes.
#pragma once

#include <optional>
#include <string>

#include "scene/scene.h"
#include "scene/scene_error.h"
#include "scene/scene_limits.h"
#include "scene/scene_load_options.h"

namespace tessera {

// Command-line overrides of the file's `image` block; validated with the same ranges.
// A target error turns the render adaptive: --spp conflicts with it (one error names both
// flags); --min-spp/--max-spp bound it; an --spp without a target makes a scene's adaptive
// settings a uniform render again.
struct ImageOverrides {
  std::optional<int> width, height, spp, max_depth;
  std::optional<uint64_t> seed;
  std::optional<SamplerKind> sampler;
  std::optional<double> target_rmse, block_rmse;
  std::optional<int> min_spp, max_spp;
  std::optional<double> roulette_weight;
};

// The scene in a file: a glTF file (.gltf, .glb) as a whole scene (gltf_scene.h), any other as
// scene JSON. Throws SceneError with a message naming the file, the JSON path and what is allowed.
Scene load_scene(const std::string& path, const SceneLoadOptions& options = {});
// Parses scene JSON text; `path` names the file in messages and anchors relative mesh paths.
Scene parse_scene(const std::string& json_text, const std::string& path, const SceneLoadOptions& options = {});
// Primitives the renderer builds for the scene: triangles of every object's mesh + analytic objects.
uint64_t primitive_count(const Scene& scene);
void apply_overrides(Scene& scene, const ImageOverrides& overrides);

// "sobol" (the default), "cmj", "independent", "center"; "stratified" names the default.
std::optional<SamplerKind> sampler_from_name(const std::string& name);
// The accepted names, for messages: "sobol, stratified, cmj, independent, center".
const char* sampler_names();
const char* sampler_name(SamplerKind kind);

}  // namespace tessera

// Reads a scene file (JSON, see docs/scene-format.md) into a Scene, loading its meshes.
#pragma once

#include <optional>
#include <string>

#include "scene/scene.h"
#include "scene/scene_error.h"

namespace tessera {

// Command-line overrides of the file's `image` block; validated with the same ranges.
// A target error turns the render adaptive: --spp conflicts with it (one error names both
// flags); --min-spp/--max-spp bound it; an --spp without a target makes a scene's adaptive
// settings a uniform render again.
struct ImageOverrides {
  std::optional<int> width, height, spp, max_depth;
  std::optional<uint64_t> seed;
  std::optional<SamplerKind> sampler;
  std::optional<double> target_rmse;
  std::optional<int> min_spp, max_spp;
};

// How a glTF scene file is read (gltf_scene.h); load_scene refuses them for other scene files.
struct GltfOptions {
  static constexpr double kDefaultFps = 24, kMaxFps = 1000;
  std::string camera;     // the camera (glTF camera name or its node's name); empty: the first
  int scene_index = -1;   // glTF `scenes` index; -1: the file's `scene`, else 0
  double fps = kDefaultFps;  // frames per second of animation time, in (0, kMaxFps]: frame F is at F / fps s
  // Whether any differs from the defaults (the farm carries only those: tessera.v1.ImageOverrides).
  bool given() const { return !camera.empty() || scene_index != -1 || fps != kDefaultFps; }
};

// Limits for scenes from untrusted peers (the coordinator and workers load scenes from bundles).
struct SceneLoadOptions {
  // When set, every file the scene reads (meshes) must lie inside this directory: a bundle's
  // scene may not read "/etc/passwd", "/dev/zero" or "../../x" on the machine that loads it.
  std::string confine_to;
  // Most primitives (triangles of every mesh instance, plus each sphere and plane); 0: no limit.
  // Checked while loading, before an object's mesh is copied, so a scene that instances one big
  // mesh many times is refused before it takes the memory.
  uint64_t max_primitives = 0;
  GltfOptions gltf;
  // Most texture pixels (all glTF images together) and most bytes of one file a glTF reads.
  uint64_t max_texture_pixels = uint64_t(1) << 28;
  uint64_t max_file_bytes = uint64_t(1) << 31;
};

// Throws SceneError with a message naming the file, the JSON path and what is allowed.
Scene load_scene(const std::string& path, const SceneLoadOptions& options = {});
// Parses scene JSON text; `path` names the file in messages and anchors relative mesh paths.
Scene parse_scene(const std::string& json_text, const std::string& path, const SceneLoadOptions& options = {});
// Primitives the renderer builds for the scene: triangles of every object's mesh + analytic objects.
uint64_t primitive_count(const Scene& scene);
void apply_overrides(Scene& scene, const ImageOverrides& overrides);

// Allowed ranges, shared by the parser, the CLI and the coordinator's limits.
struct SceneLimits {
  static constexpr int kMaxResolution = 16384;
  static constexpr int kMaxSpp = 65536;
  static constexpr int kMaxDepth = 64;
  static constexpr int kMaxFrames = 100000;
};

// "sobol" (the default), "cmj", "independent", "center"; "stratified" names the default.
std::optional<SamplerKind> sampler_from_name(const std::string& name);
// The accepted names, for messages: "sobol, stratified, cmj, independent, center".
const char* sampler_names();
const char* sampler_name(SamplerKind kind);

}  // namespace tessera

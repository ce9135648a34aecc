// SPDX-License-Identifier: Apache-2.0
// Fuzz target: the glTF scene reader (gltf_scene.cpp + tinygltf + the texture decoders), on a
// .gltf or .glb file's bytes as a bundle would carry them. The only accepted failure is
// SceneError; any other exception, crash, leak or undefined behaviour is a bug. External URIs
// are confined to a directory that does not exist, so only embedded (data URI / GLB) buffers
// and images are ever read.
#include <spdlog/spdlog.h>

#include <cstdint>
#include <cstdlib>
#include <string>

#include "scene/animation.h"
#include "scene/gltf_scene.h"
#include "scene/scene_parser.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    spdlog::set_level(spdlog::level::off);
    return true;
  }();
  (void)quiet;
  tessera::SceneLoadOptions options;
  options.confine_to = "/nonexistent-tessera-fuzz";
  options.max_primitives = 1000000;
  options.max_texture_pixels = 1 << 20;
  try {
    tessera::Scene scene = tessera::parse_gltf_scene(std::string(reinterpret_cast<const char*>(data), size),
                                                     "/nonexistent-tessera-fuzz/scene.gltf", options);
    // Invariants of an accepted scene: limits held, references valid, every frame evaluates.
    if (scene.frame_count() < 1 || scene.frame_count() > tessera::SceneLimits::kMaxFrames) std::abort();
    if (tessera::primitive_count(scene) > options.max_primitives) std::abort();
    for (const auto& o : scene.objects) {
      if (o.mesh < 0 || size_t(o.mesh) >= scene.meshes.size()) std::abort();
    }
    for (const auto& m : scene.meshes) {
      for (uint32_t i : m.indices) {
        if (i >= m.positions.size()) std::abort();
      }
      for (uint32_t id : m.material_ids) {
        if (id >= scene.materials.size()) std::abort();
        const int t = scene.materials[id].albedo_texture;
        if (t >= 0 && (size_t(t) >= scene.textures.size() || m.uvs.size() != 2 * m.positions.size())) std::abort();
      }
    }
    tessera::evaluate_frame(scene, 0);
    tessera::evaluate_frame(scene, scene.frame_count() - 1);
  } catch (const tessera::SceneError&) {
  }
  return 0;
}

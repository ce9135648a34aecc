// SPDX-License-Identifier: Apache-2.0
// How a scene file is loaded: limits for scenes from untrusted peers, and the choices a glTF
// scene leaves open (camera, scene, frame rate). Shared by the scene file parser and the glTF
// reader, which load_scene picks between by the file's name.
#pragma once

#include <cstdint>
#include <string>

namespace tessera {

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

}  // namespace tessera

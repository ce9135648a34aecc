// SPDX-License-Identifier: Apache-2.0
// A glTF 2.0 file (.gltf + buffers, or .glb) as a whole scene: camera, KHR_lights_punctual
// lights, materials mapped to the Whitted model, the node hierarchy (instances share one mesh)
// and node animations sampled into frames. The mapping is in docs/scene-format.md, "From
// Blender and other tools".
#pragma once

#include <string>

#include "scene/scene.h"
#include "scene/scene_error.h"
#include "scene/scene_load_options.h"

namespace tessera {

// True for the file names load_scene() reads as glTF (.gltf, .glb; any case).
bool is_gltf_path(const std::string& path);

// Throws SceneError naming the file and the glTF path of the fault, e.g.
// "a.gltf: meshes[2].primitives[0].indices: accessor 7 reads past the end of bufferView 3".
Scene load_gltf_scene(const std::string& path, const SceneLoadOptions& options);
// The same for the file's bytes (a .glb by its "glTF" magic, else JSON); `path` names the file in
// messages and anchors relative URIs (the fuzz target's entry).
Scene parse_gltf_scene(const std::string& bytes, const std::string& path, const SceneLoadOptions& options);

}  // namespace tessera

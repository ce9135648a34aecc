// SPDX-License-Identifier: Apache-2.0
// glTF punctual lights (KHR_lights_punctual) in radiometric units (docs/scene-format.md): point,
// spot and directional, placed by their nodes' world transforms at frame 0.
#pragma once

#include <string>
#include <vector>

#include "scene/gltf_animation.h"
#include "scene/gltf_node_tree.h"
#include "scene/gltf_reader.h"
#include "scene/scene.h"

namespace tessera {

// Appends a light for every node instance that carries one, in walk order. An animated light
// keeps its frame-0 pose (with a warning naming `path`).
void read_gltf_lights(const GltfReader& r, const GltfNodeTree& tree, const GltfAnimation& animation,
                      const std::string& path, std::vector<Light>* lights);

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// glTF mesh instances as scene objects: one per node instance with a mesh that has triangles,
// all instances of a mesh sharing it, each placed by its node's world transform at frame 0.
#pragma once

#include <string>
#include <vector>

#include "scene/gltf_animation.h"
#include "scene/gltf_node_tree.h"
#include "scene/gltf_reader.h"
#include "scene/scene.h"
#include "scene/scene_load_options.h"

namespace tessera {

// Appends the objects to scene->objects (scene->meshes already read; `file_name` becomes each
// object's file) and returns each appended object's node instance. Skinned meshes render in
// their bind pose, with one warning naming `path`. Holds options.max_primitives.
std::vector<const NodeInstance*> place_gltf_objects(const GltfReader& r, const GltfNodeTree& tree,
                                                    const GltfAnimation& animation, const std::string& path,
                                                    const std::string& file_name, const SceneLoadOptions& options,
                                                    Scene* scene);

}  // namespace tessera

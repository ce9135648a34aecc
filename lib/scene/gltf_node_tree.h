// SPDX-License-Identifier: Apache-2.0
// The glTF scene to show as node instances: every path from one of its root nodes to a node is
// one instance (a node reached along two paths is drawn twice, sharing its mesh), each node with
// its local transform at rest.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "math/transform.h"
#include "scene/gltf_reader.h"
#include "scene/scene_load_options.h"

namespace tessera {

// A node as the scene uses it: the path from a root to it.
struct NodeInstance {
  std::vector<int> chain;  // node indices, root first, this node last
};

struct GltfNodeTree {
  std::string spath;  // "scenes[i]", the scene shown, for messages
  // Local transforms of every node at rest (animations replace parts of them per frame); a node
  // written as a matrix has it in rest_matrix, which then stands for its TRS.
  std::vector<Trs> rest;
  std::vector<std::optional<Matrix4>> rest_matrix;
  std::vector<NodeInstance> instances;  // depth first, in the order the file lists children
};

// The scene options.scene_index picks (-1: the file's `scene`, else 0), its nodes checked:
// finite transforms, no cycles, at most 256 deep and 1000000 instances. Throws SceneError.
GltfNodeTree read_gltf_node_tree(const GltfReader& r, const std::string& path, const GltfOptions& options);

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_node_tree.h"

#include <algorithm>
#include <cmath>
#include <functional>

namespace tessera {

namespace {

// The index of the scene to show; its glTF path is idx("scenes", index).
int select_scene(const GltfReader& r, const std::string& path, const GltfOptions& options) {
  const tinygltf::Model& model = r.g_;
  if (model.scenes.empty()) r.fail("scenes", "the file has no scene");
  int si = options.scene_index >= 0 ? options.scene_index : (model.defaultScene >= 0 ? model.defaultScene : 0);
  if (options.scene_index < -1 || si < 0 || size_t(si) >= model.scenes.size()) {
    const std::string which = options.scene_index == -1 ? "scene " : "--scene-index ";
    throw SceneError(path + ": " + which + std::to_string(options.scene_index == -1 ? si : options.scene_index) +
                     ": must be in [0, " + std::to_string(model.scenes.size() - 1) + "] (the file's scenes)");
  }
  return si;
}

// Every node's local transform at rest, checked finite (whether the scene shows it or not).
void read_rest_poses(const GltfReader& r, GltfNodeTree* tree) {
  const tinygltf::Model& model = r.g_;
  std::vector<Trs>& rest = tree->rest;
  std::vector<std::optional<Matrix4>>& rest_matrix = tree->rest_matrix;
  rest.resize(model.nodes.size());
  rest_matrix.resize(model.nodes.size());
  for (size_t n = 0; n < model.nodes.size(); ++n) {
    const auto& node = model.nodes[n];
    const std::string np = idx("nodes", n);
    auto finite_all = [&](const std::vector<double>& v, size_t want, const char* field) {
      if (v.empty()) return false;
      if (v.size() != want) r.fail(np + "." + field, "must have " + std::to_string(want) + " numbers");
      for (double x : v) {
        if (!std::isfinite(x) || std::abs(x) > 1e15) r.fail(np + "." + field, "must be finite numbers within +-1e15");
      }
      return true;
    };
    if (finite_all(node.matrix, 16, "matrix")) {
      Matrix4 m;
      std::copy(node.matrix.begin(), node.matrix.end(), m.m.begin());
      rest_matrix[n] = m;
    }
    if (finite_all(node.translation, 3, "translation")) rest[n].t = {node.translation[0], node.translation[1], node.translation[2]};
    if (finite_all(node.rotation, 4, "rotation")) {
      rest[n].q = {node.rotation[0], node.rotation[1], node.rotation[2], node.rotation[3]};
      if (!(std::abs(rest[n].q[0]) + std::abs(rest[n].q[1]) + std::abs(rest[n].q[2]) + std::abs(rest[n].q[3]) > 0)) {
        r.fail(np + ".rotation", "must not be the zero quaternion");
      }
    }
    if (finite_all(node.scale, 3, "scale")) rest[n].s = {node.scale[0], node.scale[1], node.scale[2]};
  }
}

// Walk the scene: every path from a root to a node is an instance. A node met again on its own
// path is a cycle (glTF forbids it); the walk is bounded so a DAG cannot explode.
void walk_scene(const GltfReader& r, int si, GltfNodeTree* tree) {
  const tinygltf::Model& model = r.g_;
  std::vector<NodeInstance>& instances = tree->instances;
  constexpr size_t kMaxInstances = 1000000;
  std::vector<int> chain;
  std::function<void(int, const std::string&)> walk = [&](int n, const std::string& where) {
    if (n < 0 || size_t(n) >= model.nodes.size()) r.fail(where, "node " + std::to_string(n) + " does not exist");
    if (std::find(chain.begin(), chain.end(), n) != chain.end()) {
      r.fail(where, "node " + std::to_string(n) + " is its own ancestor (the hierarchy has a cycle)");
    }
    if (chain.size() >= 256) r.fail(where, "the node hierarchy is deeper than 256");
    if (instances.size() >= kMaxInstances) r.fail(where, "more than 1000000 node instances");
    chain.push_back(n);
    instances.push_back({chain});
    const auto& children = model.nodes[size_t(n)].children;
    for (size_t c = 0; c < children.size(); ++c) walk(children[c], idx("nodes", size_t(n)) + "." + idx("children", c));
    chain.pop_back();
  };
  const auto& roots = model.scenes[size_t(si)].nodes;
  for (size_t k = 0; k < roots.size(); ++k) walk(roots[k], tree->spath + "." + idx("nodes", k));
}

}  // namespace

GltfNodeTree read_gltf_node_tree(const GltfReader& r, const std::string& path, const GltfOptions& options) {
  const int si = select_scene(r, path, options);
  GltfNodeTree tree;
  tree.spath = idx("scenes", size_t(si));
  read_rest_poses(r, &tree);
  walk_scene(r, si, &tree);
  return tree;
}

}  // namespace tessera

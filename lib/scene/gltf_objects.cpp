// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_objects.h"

#include <spdlog/spdlog.h>

namespace tessera {

std::vector<const NodeInstance*> place_gltf_objects(const GltfReader& r, const GltfNodeTree& tree,
                                                    const GltfAnimation& animation, const std::string& path,
                                                    const std::string& file_name, const SceneLoadOptions& options,
                                                    Scene* scene) {
  const tinygltf::Model& model = r.g_;
  uint64_t primitives = 0;
  std::vector<const NodeInstance*> object_instance;
  std::string first_skinned;  // glTF path of the first skinned mesh node shown
  size_t skinned = 0;
  for (const NodeInstance& inst : tree.instances) {
    const auto& node = model.nodes[size_t(inst.chain.back())];
    if (node.mesh < 0) continue;
    if (node.skin >= 0 && skinned++ == 0) first_skinned = idx("nodes", size_t(inst.chain.back())) + ".skin";
    if (size_t(node.mesh) >= model.meshes.size()) {
      r.fail(idx("nodes", size_t(inst.chain.back())) + ".mesh", "mesh " + std::to_string(node.mesh) + " does not exist");
    }
    if (scene->meshes[size_t(node.mesh)].triangle_count() == 0) continue;
    primitives += scene->meshes[size_t(node.mesh)].triangle_count();
    if (options.max_primitives > 0 && primitives > options.max_primitives) {
      r.fail(idx("nodes", size_t(inst.chain.back())), "the scene has more than " + std::to_string(options.max_primitives) +
                                                           " primitives (triangles of every mesh instance): limit max_primitives");
    }
    SceneObject o;
    o.type = SceneObject::Type::kMesh;
    o.name = node.name;
    o.mesh = node.mesh;
    o.file = file_name;
    o.transform.matrix = animation.world_at(inst, 0).affine();
    scene->objects.push_back(std::move(o));
    object_instance.push_back(&inst);
  }
  // Skins are not evaluated: a skinned mesh renders in its bind pose (its vertices as stored,
  // placed by its node), never silently.
  if (skinned) {
    spdlog::warn("{}: {}: skins are not supported: {} skinned mesh instance{} render{} in the bind pose, "
                 "without the joints' transforms or animation (apply the armature before export to pose them)",
                 path, first_skinned, skinned, skinned == 1 ? "" : "s", skinned == 1 ? "s" : "");
  }
  return object_instance;
}

}  // namespace tessera

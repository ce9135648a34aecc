// SPDX-License-Identifier: Apache-2.0
// The glTF camera a scene is seen through: the first camera node met in the walk, or the one
// named (its camera's name or its node's name); perspective only. glTF cameras look down their
// local -Z with +Y up.
#pragma once

#include <string>

#include "scene/gltf_animation.h"
#include "scene/gltf_node_tree.h"
#include "scene/gltf_reader.h"
#include "scene/scene.h"
#include "scene/scene_load_options.h"

namespace tessera {

class GltfCamera {
 public:
  // Picks and checks the camera (SceneError naming `path` when there is none, or none of that
  // name). An aspectRatio becomes scene->camera_aspect and sets the image height from its width.
  GltfCamera(const GltfReader& r, const GltfNodeTree& tree, const std::string& path, const GltfOptions& options,
             Scene* scene);

  const NodeInstance& instance() const { return *inst_; }
  // The camera at time t (seconds), placed by its node's world transform (scale ignored).
  CameraDesc at(const GltfAnimation& animation, double t) const;

 private:
  const GltfReader& r_;
  const NodeInstance* inst_ = nullptr;
  double yfov_ = 0;  // radians
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// glTF node animations on one timeline: every channel of every animation, frame F at time
// F / fps, sampled as the glTF spec says (LINEAR, with spherical interpolation for rotations;
// STEP; CUBICSPLINE), and the world transforms of node instances at any time.
#pragma once

#include <string>
#include <vector>

#include "math/transform.h"
#include "scene/gltf_node_tree.h"
#include "scene/gltf_reader.h"
#include "scene/scene_load_options.h"

namespace tessera {

// One animation channel: keyframes of a node's translation, rotation or scale.
struct GltfChannel {
  int node = 0;
  std::string target;          // "translation", "rotation" or "scale"
  std::vector<double> times;   // seconds, strictly increasing
  std::vector<double> values;  // n per key; CUBICSPLINE: in-tangent, value, out-tangent per key
  int n = 3;                   // components: 4 for a rotation (x, y, z, w), else 3
  std::string interp;          // "LINEAR", "STEP" or "CUBICSPLINE"
};

class GltfAnimation {
 public:
  // Reads and checks every channel (morph target weights are skipped: geometry stays), then
  // options.fps and the frame count the longest channel needs; an animated node must be written
  // as TRS. Throws SceneError naming `path`.
  GltfAnimation(const GltfReader& r, const GltfNodeTree& tree, const std::string& path, const GltfOptions& options);

  int frame_count() const { return frame_count_; }  // 1 without channels
  double fps() const { return fps_; }
  // The instance's world transform at time t (seconds): its nodes' local transforms, root first.
  Matrix4 world_at(const NodeInstance& inst, double t) const;
  // Whether a channel drives any node on the instance's path.
  bool is_animated(const NodeInstance& inst) const;

 private:
  // The local transform of node n at time t (rest pose where no channel drives it).
  Matrix4 local_at(int n, double t, bool animated) const;

  const GltfNodeTree& tree_;
  std::vector<GltfChannel> channels_;
  std::vector<bool> node_animated_;
  double fps_ = GltfOptions::kDefaultFps;
  int frame_count_ = 1;
};

}  // namespace tessera

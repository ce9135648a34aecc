// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_camera.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "scene/scene_limits.h"

namespace tessera {

namespace {

// The camera node instance: the first in the walk, or the one named (camera name or node name).
const NodeInstance* select_camera(const GltfReader& r, const GltfNodeTree& tree, const std::string& path,
                                  const GltfOptions& options) {
  const tinygltf::Model& model = r.g_;
  const NodeInstance* cam = nullptr;
  std::string cam_names;
  for (const NodeInstance& inst : tree.instances) {
    const auto& node = model.nodes[size_t(inst.chain.back())];
    if (node.camera < 0) continue;
    if (size_t(node.camera) >= model.cameras.size()) {
      r.fail(idx("nodes", size_t(inst.chain.back())) + ".camera", "camera " + std::to_string(node.camera) + " does not exist");
    }
    const auto& c = model.cameras[size_t(node.camera)];
    cam_names += (cam_names.empty() ? "'" : ", '") + (c.name.empty() ? node.name : c.name) + "'";
    if (!cam && (options.camera.empty() || options.camera == c.name || options.camera == node.name)) {
      cam = &inst;
    }
  }
  if (!cam) {
    if (!options.camera.empty()) {
      throw SceneError(path + ": --camera '" + options.camera + "': no camera or camera node of " + tree.spath +
                       " has that name (cameras: " + (cam_names.empty() ? "none" : cam_names) + ")");
    }
    throw SceneError(path + ": " + tree.spath + " has no camera (export with cameras included: Blender's glTF "
                     "exporter, Include > Data > Cameras)");
  }
  return cam;
}

}  // namespace

GltfCamera::GltfCamera(const GltfReader& r, const GltfNodeTree& tree, const std::string& path,
                       const GltfOptions& options, Scene* scene)
    : r_(r), inst_(select_camera(r, tree, path, options)) {
  const tinygltf::Model& model = r.g_;
  const int cam_index = model.nodes[size_t(inst_->chain.back())].camera;
  const auto& gcam = model.cameras[size_t(cam_index)];
  const std::string cpath = idx("cameras", size_t(cam_index));
  if (gcam.type != "perspective") {
    r.fail(cpath + ".type", "'" + gcam.type + "' cameras are not supported: Tessera renders perspective cameras only");
  }
  const double yfov = gcam.perspective.yfov;
  if (!(yfov > 0 && yfov < std::numbers::pi)) r.fail(cpath + ".perspective.yfov", "must be in (0, pi) radians");
  if (gcam.perspective.aspectRatio != 0) {
    const double a = gcam.perspective.aspectRatio;
    if (!(a > 1e-4 && a < 1e4)) r.fail(cpath + ".perspective.aspectRatio", "must be in (1e-4, 1e4)");
    scene->camera_aspect = a;
    scene->image.height = std::clamp(int(std::lround(scene->image.width / a)), 1, SceneLimits::kMaxResolution);
  }
  yfov_ = yfov;
}

CameraDesc GltfCamera::at(const GltfAnimation& animation, double t) const {
  const Matrix4 m = animation.world_at(*inst_, t);
  CameraDesc c;
  c.form = CameraDesc::Form::kLookAt;
  // glTF cameras look down their local -Z with +Y up; scale is ignored (normalized).
  c.position = m.column(3);
  const Vec3d back = m.column(2), up = m.column(1);
  if (!(length(back) > 0) || !(length(up) > 0) || length(cross(normalize(back), normalize(up))) < 1e-9) {
    r_.fail(idx("nodes", size_t(inst_->chain.back())), "the camera's transform is degenerate");
  }
  c.look_at = c.position - normalize(back);
  c.up = normalize(up);
  c.vfov_deg = yfov_ * 180.0 / std::numbers::pi;
  return c;
}

}  // namespace tessera

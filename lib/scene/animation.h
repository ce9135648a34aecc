// SPDX-License-Identifier: Apache-2.0
// Frame F of a scene: the camera and the object transforms at F, by linear interpolation of
// keyframes (held constant before the first and after the last). Pure function of (scene, F).
#pragma once

#include <vector>

#include "scene/scene.h"

namespace tessera {

struct FrameState {
  int frame = 0;
  CameraDesc camera;
  std::vector<TransformDesc> transforms;  // one per Scene::objects entry
};

FrameState evaluate_frame(const Scene& scene, int frame);

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Scenes the renderer's tests share.
#pragma once

#include <string>

namespace tessera::test {

// Five objects of every material under a point and a directional light, over a checker plane: a
// small Whitted showcase whose error sits on edges, in the glass and in the mirror.
inline std::string whitted_like(int w, int h, int spp) {
  return R"({
    "camera": {"position": [0, 1.6, 6.5], "look_at": [0, 0.9, 0], "vfov_deg": 40},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) +
         R"(, "spp": )" + std::to_string(spp) + R"(, "max_depth": 6, "seed": 3},
    "background": [0.25, 0.45, 0.8],
    "lights": [{"type": "point", "position": [-4, 6, 5], "intensity": 160},
               {"type": "directional", "direction": [0.3, -1, -0.2], "irradiance": 0.5}],
    "materials": {
      "c": {"type": "diffuse", "albedo": [0.85, 0.1, 0.08], "checker": {"albedo2": [0.9, 0.85, 0.15]}},
      "mi": {"type": "mirror", "reflectance": 0.9}, "g": {"type": "glass", "ior": 1.5},
      "d": {"type": "diffuse", "albedo": [0.2, 0.5, 0.25]}},
    "objects": [
      {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "c"},
      {"type": "sphere", "center": [-1.5, 1, -0.8], "radius": 1, "material": "mi"},
      {"type": "sphere", "center": [0.55, 0.8, 1.4], "radius": 0.8, "material": "g"},
      {"type": "sphere", "center": [2, 0.7, -0.6], "radius": 0.7, "material": "d"}]
  })";
}

}  // namespace tessera::test

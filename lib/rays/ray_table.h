// SPDX-License-Identifier: Apache-2.0
// Rays and their answers as the `tessera rays` command reads and writes them (CSV, .npy): the
// rays, the optional client ids, and the names hits refer to.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "rays/hit_fields.h"
#include "rays/world_ray.h"

namespace tessera::rays {

struct RayTable {
  std::vector<WorldRay> rays;
  std::vector<uint64_t> ids;  // empty, or one per ray
};

struct HitTable {
  std::vector<WorldHit> hits;        // one per ray
  std::vector<std::string> objects;  // names: WorldHit::object indexes these
  std::vector<std::string> materials;
  bool occlusion = false;            // only `hit` is meaningful
  HitFields fields = HitFields::all();  // nearest hits: the fields written besides `hit` (others
                                        // may be WorldHit's defaults: not asked of the service)
};

// The name written for object/material index i: the name, or "#i" when the scene gives none;
// "" for kNoIndex (a miss).
std::string name_of(const std::vector<std::string>& names, uint32_t i);

}  // namespace tessera::rays

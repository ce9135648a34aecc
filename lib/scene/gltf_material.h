// SPDX-License-Identifier: Apache-2.0
// glTF materials on the Whitted model (docs/scene-format.md, "From Blender and other tools"):
// metallic-roughness materials become diffuse, mirror or glass by the nearest rule, with their
// base color textures decoded once each; what does not map is dropped with one warning per
// material naming it.
#pragma once

#include <cstdint>
#include <string>

#include "scene/gltf_reader.h"
#include "scene/scene.h"

namespace tessera {

// Appends the file's materials to scene->materials (their textures to scene->textures), then
// one default for primitives without a material, and returns the default's index. `file_name`
// prefixes the material names.
uint32_t read_gltf_materials(const GltfReader& r, const std::string& file_name, uint64_t max_texture_pixels,
                             Scene* scene);

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// glTF meshes as Scene meshes: one per glTF mesh (all its triangle primitives), shared by every
// node that uses it, so an instanced mesh is loaded once. Positions, the texture coordinates a
// material reads, vertex normals and indices are read through checked accessors.
#pragma once

#include <cstdint>
#include <string>

#include "scene/gltf_reader.h"
#include "scene/scene.h"

namespace tessera {

// Appends one mesh per glTF mesh to scene->meshes (scene->materials already read: a
// primitive's material picks its TEXCOORD set; `default_material` serves primitives without
// one). Points, lines, strips, fans and degenerate triangles are dropped with one warning each,
// naming `path`.
void read_gltf_meshes(const GltfReader& r, const std::string& path, uint32_t default_material, Scene* scene);

}  // namespace tessera

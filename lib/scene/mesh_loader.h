// SPDX-License-Identifier: Apache-2.0
// Loads triangle meshes with assimp (OBJ+MTL, PLY ascii/binary, glTF 2.0, ...).
#pragma once

#include <cstdint>

#include <string>
#include <vector>

#include "scene/scene.h"
#include "scene/scene_error.h"

namespace tessera {

struct MeshLoadResult {
  Mesh mesh;                          // material_ids index into `materials` (local to this file)
  std::vector<Material> materials;    // from the file (MTL etc.), mapped to Tessera materials
  // Every other file the importer read (an OBJ's .mtl, a glTF's buffers), relative to the mesh's
  // directory, in the order read: a bundle must carry them.
  std::vector<std::string> side_files;
  size_t dropped_degenerate = 0;      // zero-area triangles dropped
  size_t dropped_nonfinite = 0;       // triangles with a NaN/Inf vertex dropped
};

// Throws SceneError("<path>: ...") if the file is missing, unreadable or holds no triangles.
// Node transforms in the file are baked in. Meshes/nodes named in `exclude` are skipped.
// With `confine_to` set, every file the importer opens (the mesh and its side files: an OBJ's
// material libraries, a glTF's buffers) must lie inside that directory; one outside is refused
// and the load fails with a SceneError naming it.
// With `max_triangles` > 0, the triangles the node tree instances (each node's meshes, counted
// once per node that uses them) are counted *before* anything is flattened, and a file over the
// limit is refused with a SceneError ending in "limit max_primitives": a small file whose nodes
// instance one big mesh a thousand times must not make the loader allocate a gigabyte first.
MeshLoadResult load_mesh(const std::string& path, const std::vector<std::string>& exclude = {},
                         const std::string& confine_to = {}, uint64_t max_triangles = 0);

}  // namespace tessera

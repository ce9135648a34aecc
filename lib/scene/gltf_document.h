// SPDX-License-Identifier: Apache-2.0
// A glTF file's document as tinygltf reads it (.gltf with its buffers and images, or .glb), under
// the rules for files from untrusted peers: every file it reads lies inside the bundle and under
// the size limit, and is recorded (a bundle carries the buffers and images of a .gltf).
#pragma once

#include <tiny_gltf.h>

#include <string>
#include <vector>

#include "scene/scene_load_options.h"

namespace tessera {

// `bytes` are the file's (a .glb by its "glTF" magic, else JSON); `path` names it in messages and
// anchors relative URIs. *read gets the other files read, relative to the file's directory, in
// the order read. Images stay encoded (gltf_texture.cpp decodes them). Throws SceneError.
tinygltf::Model read_gltf_document(const std::string& bytes, const std::string& path, const SceneLoadOptions& options,
                                   std::vector<std::string>* read);

}  // namespace tessera

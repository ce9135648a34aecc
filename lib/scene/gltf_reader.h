// SPDX-License-Identifier: Apache-2.0
// Safe reads from a glTF document as tinygltf hands it over: tinygltf keeps indices and byte
// ranges as written, so every accessor is checked against its bufferView and buffer here before
// a byte is read, and every fault is one SceneError naming the file and its glTF path.
#pragma once

#include <tiny_gltf.h>

#include <initializer_list>
#include <string>

#include "scene/scene_error.h"

namespace tessera {

class GltfReader {
 public:
  GltfReader(const tinygltf::Model& model, std::string file) : g_(model), file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw SceneError(file_ + ": " + path + ": " + what);
  }

  // Bytes of accessor `index` read at `path` (e.g. "meshes[2].primitives[0].indices"), checked:
  // the element type is one of `types`, the component type one of `components`, every element
  // lies inside its bufferView and buffer. Returns the first element; *stride between elements.
  struct View {
    const unsigned char* data = nullptr;
    size_t count = 0, stride = 0;
    int type = 0, component = 0;
    bool normalized = false;
  };
  View accessor(int index, const std::string& path, std::initializer_list<int> types,
                std::initializer_list<int> components) const;

  // Element i, component c of a view as a double (normalized integers scaled to [0, 1]).
  static double component(const View& v, size_t i, int c);

  const tinygltf::Model& g_;
  std::string file_;
};

// "array[i]": one step of a glTF path in messages.
inline std::string idx(const char* array, size_t i) { return std::string(array) + "[" + std::to_string(i) + "]"; }

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_reader.h"

#include <algorithm>
#include <cstring>

namespace tessera {

GltfReader::View GltfReader::accessor(int index, const std::string& path, std::initializer_list<int> types,
                                      std::initializer_list<int> components) const {
  if (index < 0 || size_t(index) >= g_.accessors.size()) {
    fail(path, "accessor " + std::to_string(index) + " does not exist (the file has " +
                   std::to_string(g_.accessors.size()) + ")");
  }
  const tinygltf::Accessor& a = g_.accessors[size_t(index)];
  const std::string apath = path + " (accessors[" + std::to_string(index) + "])";
  if (std::find(types.begin(), types.end(), a.type) == types.end()) fail(apath, "wrong element type");
  if (std::find(components.begin(), components.end(), a.componentType) == components.end()) {
    fail(apath, "wrong component type " + std::to_string(a.componentType));
  }
  if (a.sparse.isSparse) fail(apath, "sparse accessors are not supported");
  if (a.bufferView < 0 || size_t(a.bufferView) >= g_.bufferViews.size()) {
    fail(apath, "bufferView " + std::to_string(a.bufferView) + " does not exist");
  }
  const tinygltf::BufferView& bv = g_.bufferViews[size_t(a.bufferView)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= g_.buffers.size()) {
    fail(apath, "bufferViews[" + std::to_string(a.bufferView) + "].buffer does not exist");
  }
  const auto& buf = g_.buffers[size_t(bv.buffer)].data;
  const int comp_size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
  const int ncomp = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  if (comp_size <= 0 || ncomp <= 0) fail(apath, "unknown element or component type");
  const size_t elem = size_t(comp_size) * size_t(ncomp);
  const size_t stride = bv.byteStride ? bv.byteStride : elem;
  if (stride < elem) fail(apath, "byteStride " + std::to_string(bv.byteStride) + " is smaller than an element");
  // Checked without overflow: the view lies in the buffer, the elements in the view.
  if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset) {
    fail(apath, "bufferViews[" + std::to_string(a.bufferView) + "] lies outside buffers[" +
                    std::to_string(bv.buffer) + "] (" + std::to_string(buf.size()) + " bytes)");
  }
  if (a.count == 0) fail(apath, "count is 0");
  if (a.byteOffset > bv.byteLength || (a.count - 1) > (bv.byteLength - a.byteOffset - std::min(elem, bv.byteLength - a.byteOffset)) / stride ||
      a.byteOffset + elem > bv.byteLength) {
    fail(apath, "its " + std::to_string(a.count) + " elements read past the end of bufferViews[" +
                    std::to_string(a.bufferView) + "] (" + std::to_string(bv.byteLength) + " bytes)");
  }
  return {buf.data() + bv.byteOffset + a.byteOffset, a.count, stride, a.type, a.componentType, a.normalized};
}

double GltfReader::component(const View& v, size_t i, int c) {
  const unsigned char* p = v.data + i * v.stride;
  switch (v.component) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p + 4 * c, 4); return f; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: { const double x = p[c]; return v.normalized ? x / 255.0 : x; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t s; std::memcpy(&s, p + 2 * c, 2);
      return v.normalized ? s / 65535.0 : double(s);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t u; std::memcpy(&u, p + 4 * c, 4); return double(u); }
    case TINYGLTF_COMPONENT_TYPE_BYTE: { const double x = int8_t(p[c]); return v.normalized ? std::max(x / 127.0, -1.0) : x; }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t s; std::memcpy(&s, p + 2 * c, 2);
      return v.normalized ? std::max(s / 32767.0, -1.0) : double(s);
    }
  }
  return 0;
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Test helper: writes small glTF 2.0 files (one embedded base64 buffer) from arrays, so tests
// state their geometry, lights and camera in a few lines and compare against analytic values.
#pragma once

#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace tessera::testing {

class GltfBuilder {
 public:
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}}, {"scene", 0}, {"scenes", {{{"nodes", nlohmann::json::array()}}}}};

  // Appends raw bytes as a bufferView + accessor; returns the accessor index.
  int accessor(const void* data, size_t bytes, size_t count, const char* type, int component) {
    while (bin_.size() % 4) bin_.push_back('\0');
    const size_t offset = bin_.size();
    bin_.append(static_cast<const char*>(data), bytes);
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}});
    doc["accessors"].push_back({{"bufferView", doc["bufferViews"].size() - 1}, {"componentType", component},
                                {"count", count}, {"type", type}});
    return int(doc["accessors"].size() - 1);
  }
  int floats(const std::vector<float>& v, const char* type, size_t per) {
    return accessor(v.data(), v.size() * 4, v.size() / per, type, 5126);
  }
  int indices(const std::vector<uint32_t>& v) { return accessor(v.data(), v.size() * 4, v.size(), "SCALAR", 5125); }
  // A mesh of one triangle primitive (with vertex normals if `normals` is not empty); returns the mesh index.
  int mesh(const std::vector<float>& positions, const std::vector<uint32_t>& idx, int material = -1,
           const std::vector<float>& uvs = {}, const std::vector<float>& normals = {}) {
    nlohmann::json prim = {{"attributes", {{"POSITION", floats(positions, "VEC3", 3)}}}, {"indices", indices(idx)}};
    if (!uvs.empty()) prim["attributes"]["TEXCOORD_0"] = floats(uvs, "VEC2", 2);
    if (!normals.empty()) prim["attributes"]["NORMAL"] = floats(normals, "VEC3", 3);
    if (material >= 0) prim["material"] = material;
    doc["meshes"].push_back({{"primitives", {prim}}});
    return int(doc["meshes"].size() - 1);
  }
  // Adds a node (a root of scene 0 unless `root` is false); returns its index.
  int node(nlohmann::json n, bool root = true) {
    doc["nodes"].push_back(std::move(n));
    const int i = int(doc["nodes"].size() - 1);
    if (root) doc["scenes"][0]["nodes"].push_back(i);
    return i;
  }
  int camera(double yfov, double aspect = 0) {
    nlohmann::json p = {{"yfov", yfov}, {"znear", 0.01}};
    if (aspect > 0) p["aspectRatio"] = aspect;
    doc["cameras"].push_back({{"type", "perspective"}, {"perspective", p}});
    return int(doc["cameras"].size() - 1);
  }
  int light(nlohmann::json l) {
    doc["extensions"]["KHR_lights_punctual"]["lights"].push_back(std::move(l));
    doc["extensionsUsed"] = {"KHR_lights_punctual"};
    return int(doc["extensions"]["KHR_lights_punctual"]["lights"].size() - 1);
  }
  int material(nlohmann::json m) {
    doc["materials"].push_back(std::move(m));
    return int(doc["materials"].size() - 1);
  }
  // Embeds encoded image bytes (PNG/JPEG/anything) as images[i] + textures[i]; returns the texture.
  int texture(const std::string& bytes, nlohmann::json sampler = {{"magFilter", 9728}}) {
    while (bin_.size() % 4) bin_.push_back('\0');
    const size_t offset = bin_.size();
    bin_ += bytes;
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes.size()}});
    doc["images"].push_back({{"bufferView", doc["bufferViews"].size() - 1}, {"mimeType", "image/png"}});
    doc["samplers"].push_back(std::move(sampler));
    doc["textures"].push_back({{"source", doc["images"].size() - 1}, {"sampler", doc["samplers"].size() - 1}});
    return int(doc["textures"].size() - 1);
  }
  // The document with its buffer as a data URI.
  std::string text() const {
    nlohmann::json d = doc;
    d["buffers"] = {{{"byteLength", bin_.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin_)}}};
    return d.dump();
  }
  void write(const std::string& path) const { std::ofstream(path, std::ios::binary) << text(); }
  // The .gltf at `path` with its buffer beside it as `bin_name` (a separate-files export).
  void write_separate(const std::string& path, const std::string& bin_name) const {
    nlohmann::json d = doc;
    d["buffers"] = {{{"byteLength", bin_.size()}, {"uri", bin_name}}};
    std::ofstream(path, std::ios::binary) << d.dump();
    const std::string dir = path.substr(0, path.find_last_of('/') + 1);
    std::ofstream(dir + bin_name, std::ios::binary) << bin_;
  }

 private:
  static std::string base64(const std::string& in) {
    static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    size_t i = 0;
    for (; i + 2 < in.size(); i += 3) {
      const uint32_t v = uint32_t(uint8_t(in[i])) << 16 | uint32_t(uint8_t(in[i + 1])) << 8 | uint8_t(in[i + 2]);
      out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], k[v & 63]};
    }
    if (i + 1 == in.size()) {
      const uint32_t v = uint32_t(uint8_t(in[i])) << 16;
      out += {k[v >> 18], k[(v >> 12) & 63], '=', '='};
    } else if (i + 2 == in.size()) {
      const uint32_t v = uint32_t(uint8_t(in[i])) << 16 | uint32_t(uint8_t(in[i + 1])) << 8;
      out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], '='};
    }
    return out;
  }
  std::string bin_;
};

}  // namespace tessera::testing

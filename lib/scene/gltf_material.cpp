// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_material.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <functional>
#include <map>
#include <vector>

#include "scene/gltf_texture.h"

namespace tessera {

namespace {

double ext_number(const tinygltf::ExtensionMap& exts, const char* ext, const char* key, double fallback) {
  auto it = exts.find(ext);
  if (it == exts.end() || !it->second.IsObject() || !it->second.Has(key)) return fallback;
  const tinygltf::Value& v = it->second.Get(key);
  return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
}

bool near(double a, double b) { return std::abs(a - b) <= 0.01; }

// What the Whitted model has no place for, in the order the warning lists it.
void list_unsupported(const tinygltf::Material& gm, std::vector<std::string>* dropped) {
  if (gm.emissiveTexture.index >= 0) dropped->push_back("emissive texture (the emissive factor used alone)");
  if (gm.pbrMetallicRoughness.metallicRoughnessTexture.index >= 0) dropped->push_back("metallic-roughness texture");
  if (gm.normalTexture.index >= 0) dropped->push_back("normal map");
  if (gm.alphaMode != "OPAQUE" && !gm.alphaMode.empty()) dropped->push_back("alpha " + gm.alphaMode + " (opaque)");
  for (const char* ext : {"KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_specular",
                          "KHR_materials_volume", "KHR_materials_iridescence", "KHR_materials_anisotropy"}) {
    if (gm.extensions.count(ext)) dropped->push_back(ext);
  }
}

// glTF metallic-roughness materials on the Whitted model (docs/scene-format.md): what does not
// map is rendered by the nearest rule, with one warning per material naming what was dropped.
Material map_material(const GltfReader& r, size_t i, const std::string& file,
                      const std::function<int(int, const std::string&)>& texture_of) {
  const tinygltf::Material& gm = r.g_.materials[i];
  const std::string path = idx("materials", i);
  Material m;
  m.name = file + ":" + (gm.name.empty() ? path : gm.name);
  const auto& pbr = gm.pbrMetallicRoughness;
  if (pbr.baseColorFactor.size() != 4) r.fail(path + ".pbrMetallicRoughness.baseColorFactor", "must have 4 numbers");
  Rgb base(float(pbr.baseColorFactor[0]), float(pbr.baseColorFactor[1]), float(pbr.baseColorFactor[2]));
  auto unit = [&](double v, const std::string& field) {
    if (!(v >= 0 && v <= 1)) r.fail(path + "." + field, "must be in [0, 1], got " + std::to_string(v));
    return v;
  };
  for (int c = 0; c < 3; ++c) unit(pbr.baseColorFactor[size_t(c)], "pbrMetallicRoughness.baseColorFactor");
  const double metallic = unit(pbr.metallicFactor, "pbrMetallicRoughness.metallicFactor");
  const double roughness = unit(pbr.roughnessFactor, "pbrMetallicRoughness.roughnessFactor");
  const double transmission = unit(ext_number(gm.extensions, "KHR_materials_transmission", "transmissionFactor", 0),
                                   "extensions.KHR_materials_transmission.transmissionFactor");
  const double ior = ext_number(gm.extensions, "KHR_materials_ior", "ior", 1.5);
  std::vector<std::string> dropped;
  if (transmission > 0) {
    m.type = Material::Type::kGlass;
    m.ior = ior;
    if (!(ior >= 1.0 && ior <= 10.0)) {
      dropped.push_back("ior " + std::to_string(ior) + " outside [1, 10] (1.5 used)");
      m.ior = 1.5;
    }
    m.transmittance = base;
    if (!near(transmission, 1)) dropped.push_back("partial transmission (rendered as full glass)");
    if (!near(roughness, 0)) dropped.push_back("rough transmission (rendered as smooth glass)");
  } else if (metallic >= 0.5 && roughness <= 0.5) {
    m.type = Material::Type::kMirror;
    m.reflectance = base;
    if (!near(metallic, 1) || !near(roughness, 0)) dropped.push_back("rough or partly metallic (rendered as a mirror)");
  } else {
    m.type = Material::Type::kDiffuse;
    m.albedo = base;
    if (metallic >= 0.5) dropped.push_back("rough metal (rendered diffuse)");
  }
  if (pbr.baseColorTexture.index >= 0) {
    if (m.type == Material::Type::kDiffuse) {
      m.albedo_texture = texture_of(pbr.baseColorTexture.index, path + ".pbrMetallicRoughness.baseColorTexture");
      m.uv_set = pbr.baseColorTexture.texCoord;
      m.uv_transform = read_texture_transform(pbr.baseColorTexture.extensions, &m.uv_set);
      if (m.uv_set < 0 || m.uv_set > 7) r.fail(path + ".pbrMetallicRoughness.baseColorTexture.texCoord", "must be in [0, 7]");
    } else {
      dropped.push_back("base color texture on a mirror or glass (its factor used)");
    }
  }
  // Emission: factor x strength; an emissive texture is dropped (the factor alone is used).
  if (gm.emissiveFactor.size() == 3) {
    const double strength = ext_number(gm.extensions, "KHR_materials_emissive_strength", "emissiveStrength", 1.0);
    if (!(strength >= 0 && strength <= 1e15)) r.fail(path + ".extensions.KHR_materials_emissive_strength", "must be >= 0");
    for (int c = 0; c < 3; ++c) {
      unit(gm.emissiveFactor[size_t(c)], "emissiveFactor");
      m.emission[c] = float(gm.emissiveFactor[size_t(c)] * strength);
    }
  }
  list_unsupported(gm, &dropped);
  if (!dropped.empty()) {
    std::string list;
    for (const auto& d : dropped) list += (list.empty() ? "" : "; ") + d;
    spdlog::warn("{}: {} '{}': not in the Whitted model, nearest rule used: {}", file, path, gm.name, list);
  }
  return m;
}

}  // namespace

uint32_t read_gltf_materials(const GltfReader& r, const std::string& file_name, uint64_t max_texture_pixels,
                             Scene* scene) {
  const tinygltf::Model& model = r.g_;
  // Textures: decoded once per (image, sampler) on first use by a material.
  TextureDecoder decoder(model, r.file_, max_texture_pixels, &scene->textures);
  std::map<int, int> texture_index;
  auto texture_of = [&](int t, const std::string& where) {
    if (t < 0 || size_t(t) >= model.textures.size()) r.fail(where + ".index", "texture " + std::to_string(t) + " does not exist");
    auto it = texture_index.find(t);
    if (it != texture_index.end()) return it->second;
    const int k = decoder.decode(size_t(t), where);
    texture_index[t] = k;
    return k;
  };

  // Materials: the file's, then one default for primitives without a material.
  for (size_t i = 0; i < model.materials.size(); ++i) {
    scene->materials.push_back(map_material(r, i, file_name, texture_of));
  }
  const uint32_t default_material = uint32_t(scene->materials.size());
  scene->materials.push_back(Material{.name = file_name + ":default"});
  return default_material;
}

}  // namespace tessera

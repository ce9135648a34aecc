// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_mesh.h"

#include <spdlog/spdlog.h>

#include <vector>

namespace tessera {

namespace {

// What was left out of the meshes, for the warnings after the last one.
struct DroppedPrimitives {
  size_t other_modes = 0, degenerate = 0;
  std::string first_morphed;  // glTF path of the first primitive with morph targets
};

// Texture coordinates of the set the material reads (TEXCOORD_n), when it has a texture.
void append_uvs(const GltfReader& r, const tinygltf::Primitive& prim, const std::string& ppath,
                const Material& material, const GltfReader::View& pos, uint32_t base, Mesh* mesh) {
  if (material.albedo_texture >= 0) {
    const std::string set = "TEXCOORD_" + std::to_string(material.uv_set);
    auto uv_it = prim.attributes.find(set);
    if (uv_it == prim.attributes.end()) r.fail(ppath + ".attributes", "has no " + set + " for its material's texture");
    const auto uv = r.accessor(uv_it->second, ppath + ".attributes." + set, {TINYGLTF_TYPE_VEC2},
                               {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
    if (uv.count != pos.count) r.fail(ppath + ".attributes." + set, "count differs from POSITION's");
    mesh->uvs.resize(2 * size_t(base), 0.0f);
    for (size_t v = 0; v < uv.count; ++v) {
      mesh->uvs.push_back(float(GltfReader::component(uv, v, 0)));
      mesh->uvs.push_back(float(GltfReader::component(uv, v, 1)));
    }
  } else if (!mesh->uvs.empty()) {
    mesh->uvs.resize(2 * mesh->positions.size(), 0.0f);
  }
}

// Vertex normals: interpolated shading normals (render/shading_normal.h). A zero or non-finite
// one is kept as zero: its triangles shade flat.
void append_normals(const GltfReader& r, const tinygltf::Primitive& prim, const std::string& ppath,
                    const GltfReader::View& pos, uint32_t base, Mesh* mesh) {
  if (auto n_it = prim.attributes.find("NORMAL"); n_it != prim.attributes.end()) {
    const auto nrm = r.accessor(n_it->second, ppath + ".attributes.NORMAL", {TINYGLTF_TYPE_VEC3},
                                {TINYGLTF_COMPONENT_TYPE_FLOAT});
    if (nrm.count != pos.count) r.fail(ppath + ".attributes.NORMAL", "count differs from POSITION's");
    mesh->normals.resize(size_t(base), Vec3f(0.0f));
    for (size_t v = 0; v < nrm.count; ++v) {
      const Vec3f n(float(GltfReader::component(nrm, v, 0)), float(GltfReader::component(nrm, v, 1)),
                    float(GltfReader::component(nrm, v, 2)));
      mesh->normals.push_back(is_finite(n) ? n : Vec3f(0.0f));
    }
  } else if (!mesh->normals.empty()) {
    mesh->normals.resize(mesh->positions.size(), Vec3f(0.0f));
  }
}

// The primitive's triangles as indices into its POSITION, three a triangle, checked against its
// count (without indices: the vertices in order).
std::vector<uint32_t> triangle_indices(const GltfReader& r, const tinygltf::Primitive& prim, const std::string& ppath,
                                       const GltfReader::View& pos) {
  std::vector<uint32_t> tri;
  if (prim.indices >= 0) {
    const auto ind = r.accessor(prim.indices, ppath + ".indices", {TINYGLTF_TYPE_SCALAR},
                                {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                 TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT});
    if (ind.count % 3) r.fail(ppath + ".indices", "count " + std::to_string(ind.count) + " is not a multiple of 3");
    tri.reserve(ind.count);
    for (size_t k = 0; k < ind.count; ++k) {
      const double i = GltfReader::component(ind, k, 0);
      if (i >= double(pos.count)) {
        r.fail(ppath + ".indices", "index " + std::to_string(uint64_t(i)) + " (element " + std::to_string(k) +
                                       ") is out of range: POSITION has " + std::to_string(pos.count) + " vertices");
      }
      tri.push_back(uint32_t(i));
    }
  } else {
    if (pos.count % 3) r.fail(ppath + ".attributes.POSITION", "count is not a multiple of 3 (no indices)");
    for (size_t k = 0; k < pos.count; ++k) tri.push_back(uint32_t(k));
  }
  return tri;
}

// The triangles that have a surface, their vertices offset by `base`, each of material `mat`.
void append_triangles(const std::vector<uint32_t>& tri, uint32_t base, uint32_t mat, Mesh* mesh,
                      size_t* dropped_degenerate) {
  for (size_t k = 0; k < tri.size(); k += 3) {
    const Vec3d a(mesh->positions[base + tri[k]]), b(mesh->positions[base + tri[k + 1]]),
        c(mesh->positions[base + tri[k + 2]]);
    if (!is_finite(a) || !is_finite(b) || !is_finite(c) || dot(cross(b - a, c - a), cross(b - a, c - a)) == 0.0) {
      ++*dropped_degenerate;  // NaN/Inf or zero area: no surface
      continue;
    }
    mesh->indices.insert(mesh->indices.end(), {base + tri[k], base + tri[k + 1], base + tri[k + 2]});
    mesh->material_ids.push_back(mat);
  }
}

// Appends one primitive's vertices and triangles to `mesh` (a glTF mesh's primitives share it).
void read_primitive(const GltfReader& r, const tinygltf::Primitive& prim, const std::string& ppath,
                    uint32_t default_material, const std::vector<Material>& materials, Mesh* mesh,
                    DroppedPrimitives* dropped) {
  if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) {
    ++dropped->other_modes;  // points, lines, strips and fans
    return;
  }
  if (!prim.targets.empty() && dropped->first_morphed.empty()) dropped->first_morphed = ppath + ".targets";
  auto pos_it = prim.attributes.find("POSITION");
  if (pos_it == prim.attributes.end()) r.fail(ppath + ".attributes", "has no POSITION");
  const auto pos = r.accessor(pos_it->second, ppath + ".attributes.POSITION", {TINYGLTF_TYPE_VEC3},
                              {TINYGLTF_COMPONENT_TYPE_FLOAT});
  const uint32_t base = uint32_t(mesh->positions.size());
  if (mesh->positions.size() + pos.count > (uint64_t(1) << 31)) r.fail(ppath, "too many vertices");
  for (size_t v = 0; v < pos.count; ++v) {
    mesh->positions.push_back(Vec3f(float(GltfReader::component(pos, v, 0)), float(GltfReader::component(pos, v, 1)),
                                    float(GltfReader::component(pos, v, 2))));
  }
  if (prim.material >= 0 && size_t(prim.material) >= r.g_.materials.size()) {
    r.fail(ppath + ".material", "material " + std::to_string(prim.material) + " does not exist");
  }
  const uint32_t mat = prim.material >= 0 ? uint32_t(prim.material) : default_material;
  append_uvs(r, prim, ppath, materials[mat], pos, base, mesh);
  append_normals(r, prim, ppath, pos, base, mesh);
  append_triangles(triangle_indices(r, prim, ppath, pos), base, mat, mesh, &dropped->degenerate);
}

}  // namespace

void read_gltf_meshes(const GltfReader& r, const std::string& path, uint32_t default_material, Scene* scene) {
  DroppedPrimitives dropped;
  for (size_t mi = 0; mi < r.g_.meshes.size(); ++mi) {
    Mesh mesh;
    const auto& gmesh = r.g_.meshes[mi];
    for (size_t pi = 0; pi < gmesh.primitives.size(); ++pi) {
      const std::string ppath = idx("meshes", mi) + "." + idx("primitives", pi);
      read_primitive(r, gmesh.primitives[pi], ppath, default_material, scene->materials, &mesh, &dropped);
    }
    for (auto& p : mesh.positions) {
      if (!is_finite(p)) p = Vec3f(0.0f);  // unreferenced now; must not reach Embree's bounds
    }
    scene->meshes.push_back(std::move(mesh));
  }
  if (dropped.other_modes) {
    spdlog::warn("{}: {} primitives that are not triangles (points, lines, strips, fans) ignored", path,
                 dropped.other_modes);
  }
  if (!dropped.first_morphed.empty()) {
    spdlog::warn("{}: {}: morph targets are not supported: meshes render in their base shape, and animations of "
                 "their weights are ignored", path, dropped.first_morphed);
  }
  if (dropped.degenerate) {
    spdlog::warn("{}: dropped {} triangles with a NaN/Inf vertex or zero area", path, dropped.degenerate);
  }
}

}  // namespace tessera

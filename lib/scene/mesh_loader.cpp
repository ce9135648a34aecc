// SPDX-License-Identifier: Apache-2.0
#include "scene/mesh_loader.h"

#include <assimp/DefaultIOSystem.h>
#include <assimp/ObjMaterial.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <filesystem>

namespace tessera {

namespace {

namespace fs = std::filesystem;

// Assimp opens a model's side files itself (an OBJ's mtllib, a glTF's buffers), wherever their
// names point. This IO system records every file it opens, so bundles can carry them (assimp
// reports none of them), and, when confined, refuses files outside a directory and remembers
// them for load_mesh's error: a scene from a bundle must read nothing else. Paths are compared
// after resolving symlinks and "..", so neither can lead out.
class TrackingIOSystem : public Assimp::DefaultIOSystem {
 public:
  explicit TrackingIOSystem(const std::string& confine_to) {
    if (!confine_to.empty()) root_ = resolve(confine_to);
  }
  bool Exists(const char* file) const override { return allowed(file) && DefaultIOSystem::Exists(file); }
  Assimp::IOStream* Open(const char* file, const char* mode = "rb") override {
    if (!allowed(file)) return nullptr;
    Assimp::IOStream* stream = DefaultIOSystem::Open(file, mode);
    if (stream) {
      const fs::path p = resolve(file);
      if (std::find(opened_.begin(), opened_.end(), p) == opened_.end()) opened_.push_back(p);
    }
    return stream;
  }
  const std::vector<std::string>& refused() const { return refused_; }
  const std::vector<fs::path>& opened() const { return opened_; }  // resolved, in order
  static fs::path resolve(const fs::path& p) {
    std::error_code ec;
    fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
    return ec ? fs::absolute(p).lexically_normal() : r;
  }

 private:
  bool allowed(const char* file) const {
    if (root_.empty()) return true;
    const fs::path rel = resolve(file).lexically_relative(root_);
    if (!rel.empty() && *rel.begin() != "..") return true;
    if (std::find(refused_.begin(), refused_.end(), file) == refused_.end()) refused_.emplace_back(file);
    return false;
  }
  fs::path root_;
  mutable std::vector<std::string> refused_;
  std::vector<fs::path> opened_;
};

Rgb color_or(const aiMaterial* m, const char* key, unsigned type, unsigned idx, Rgb fallback) {
  aiColor3D c;
  if (m->Get(key, type, idx, c) == AI_SUCCESS) return {c.r, c.g, c.b};
  return fallback;
}

bool finite_rgb(const Rgb& c) { return is_finite(c) && c.x >= 0 && c.y >= 0 && c.z >= 0; }

// MTL mapping (the classic Wavefront illumination models): illum 5 = mirror (Ks),
// illum 7 = glass (Ni, Tf), anything else = diffuse (Kd); Ke on any of them = emitter.
Material map_material(const aiMaterial* m, const std::string& file) {
  Material out;
  aiString name;
  m->Get(AI_MATKEY_NAME, name);
  out.name = file + ":" + name.C_Str();
  int illum = 2;
  m->Get(AI_MATKEY_OBJ_ILLUM, illum);
  out.albedo = color_or(m, AI_MATKEY_COLOR_DIFFUSE, Rgb(0.8f));
  out.emission = color_or(m, AI_MATKEY_COLOR_EMISSIVE, Rgb(0.0f));
  if (illum == 5) {
    out.type = Material::Type::kMirror;
    out.reflectance = color_or(m, AI_MATKEY_COLOR_SPECULAR, Rgb(1.0f));
  } else if (illum == 7) {
    out.type = Material::Type::kGlass;
    float ior = 1.5f;
    m->Get(AI_MATKEY_REFRACTI, ior);
    out.ior = ior;
    out.transmittance = color_or(m, AI_MATKEY_COLOR_TRANSPARENT, Rgb(1.0f));
  }
  // Files in the wild carry garbage; clamp to what the renderer accepts, deterministically.
  auto sane = [](Rgb c, Rgb fallback) { return finite_rgb(c) ? c : fallback; };
  out.albedo = sane(out.albedo, Rgb(0.8f));
  out.albedo = vmin(out.albedo, Rgb(1.0f));
  out.emission = sane(out.emission, Rgb(0.0f));
  out.reflectance = vmin(sane(out.reflectance, Rgb(1.0f)), Rgb(1.0f));
  out.transmittance = vmin(sane(out.transmittance, Rgb(1.0f)), Rgb(1.0f));
  if (!std::isfinite(out.ior) || out.ior < 1.0 || out.ior > 10.0) out.ior = 1.5;
  return out;
}

}  // namespace

MeshLoadResult load_mesh(const std::string& path, const std::vector<std::string>& exclude,
                         const std::string& confine_to, uint64_t max_triangles) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw SceneError(path + ": mesh file not found");
  }
  Assimp::Importer importer;
  auto* io = new TrackingIOSystem(confine_to);
  importer.SetIOHandler(io);  // the importer owns it
  // Drop points and lines: only triangles are surfaces.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  const aiScene* ai = importer.ReadFile(
      path, aiProcess_Triangulate | aiProcess_SortByPType | aiProcess_ValidateDataStructure);
  if (!io->refused().empty()) {
    throw SceneError(path + ": refers to '" + io->refused().front() +
                     "', which is outside the scene bundle (side files such as an OBJ's mtllib or a glTF's "
                     "buffers must lie in the bundle's directory)");
  }
  if (ai == nullptr || ai->mRootNode == nullptr) {
    throw SceneError(path + ": cannot load mesh: " + importer.GetErrorString());
  }
  MeshLoadResult result;
  const std::string file_name = std::filesystem::path(path).filename().string();
  for (unsigned i = 0; i < ai->mNumMaterials; ++i) {
    result.materials.push_back(map_material(ai->mMaterials[i], file_name));
  }
  if (result.materials.empty()) result.materials.push_back(Material{.name = file_name + ":default"});
  const fs::path self = TrackingIOSystem::resolve(path);
  for (const fs::path& f : io->opened()) {
    if (f != self) result.side_files.push_back(f.lexically_relative(self.parent_path()).generic_string());
  }

  auto excluded = [&](const aiString& n) {
    return std::find(exclude.begin(), exclude.end(), std::string(n.C_Str())) != exclude.end();
  };
  if (max_triangles > 0) {
    // Count what the walk below would create, without creating it (faces, per node instance).
    uint64_t total = 0;
    std::vector<const aiNode*> todo{ai->mRootNode};
    while (!todo.empty()) {
      const aiNode* node = todo.back();
      todo.pop_back();
      if (node != ai->mRootNode && excluded(node->mName)) continue;
      for (unsigned c = 0; c < node->mNumChildren; ++c) todo.push_back(node->mChildren[c]);
      for (unsigned k = 0; k < node->mNumMeshes; ++k) {
        const aiMesh* am = ai->mMeshes[node->mMeshes[k]];
        if (excluded(am->mName) || !(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        total += am->mNumFaces;
      }
      if (total > max_triangles) {
        throw SceneError(path + ": its nodes instance more than " + std::to_string(max_triangles) +
                         " triangles (the scene has more primitives than allowed): limit max_primitives");
      }
    }
  }
  Mesh& mesh = result.mesh;
  // Walk the node tree so per-node transforms (glTF) are baked in, and named parts can be skipped.
  struct Item { const aiNode* node; aiMatrix4x4 to_root; };
  std::vector<Item> stack{{ai->mRootNode, ai->mRootNode->mTransformation}};
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    if (item.node != ai->mRootNode && excluded(item.node->mName)) continue;
    for (unsigned c = item.node->mNumChildren; c-- > 0;) {
      const aiNode* child = item.node->mChildren[c];
      stack.push_back({child, item.to_root * child->mTransformation});
    }
    for (unsigned k = 0; k < item.node->mNumMeshes; ++k) {
      const aiMesh* am = ai->mMeshes[item.node->mMeshes[k]];
      if (excluded(am->mName) || !(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
      const uint32_t base = uint32_t(mesh.positions.size());
      for (unsigned v = 0; v < am->mNumVertices; ++v) {
        const aiVector3D p = item.to_root * am->mVertices[v];
        mesh.positions.push_back({p.x, p.y, p.z});
      }
      const uint32_t mat = am->mMaterialIndex < result.materials.size() ? am->mMaterialIndex : 0;
      for (unsigned f = 0; f < am->mNumFaces; ++f) {
        const aiFace& face = am->mFaces[f];
        if (face.mNumIndices != 3) continue;
        const uint32_t i0 = base + face.mIndices[0], i1 = base + face.mIndices[1],
                       i2 = base + face.mIndices[2];
        const Vec3d a(mesh.positions[i0]), b(mesh.positions[i1]), c(mesh.positions[i2]);
        if (!is_finite(a) || !is_finite(b) || !is_finite(c)) {
          ++result.dropped_nonfinite;
          continue;
        }
        if (dot(cross(b - a, c - a), cross(b - a, c - a)) == 0.0) {
          ++result.dropped_degenerate;
          continue;
        }
        mesh.indices.insert(mesh.indices.end(), {i0, i1, i2});
        mesh.material_ids.push_back(mat);
      }
    }
  }
  if (mesh.triangle_count() == 0) {
    throw SceneError(path + ": mesh has no usable triangles" +
                     (result.dropped_nonfinite + result.dropped_degenerate
                          ? " (" + std::to_string(result.dropped_nonfinite) + " with NaN/Inf vertices, " +
                                std::to_string(result.dropped_degenerate) + " of zero area)"
                          : std::string()));
  }
  // Non-finite vertices no longer referenced must not reach Embree's bounds: zero them.
  for (auto& p : mesh.positions) {
    if (!is_finite(p)) p = Vec3f(0.0f);
  }
  return result;
}

}  // namespace tessera

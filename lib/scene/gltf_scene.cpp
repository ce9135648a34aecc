// SPDX-License-Identifier: Apache-2.0
// glTF 2.0 scenes through tinygltf (Debian's libtinygltf-dev 2.7), not assimp: assimp 5.2.5,
// which still loads meshes (mesh_loader.cpp), imports glTF cameras wrongly (its horizontal field
// of view is yfov x aspect, and the node's position is applied twice, once more as mPosition)
// and drops KHR_materials_emissive_strength. tinygltf hands over the document as written,
// KHR_lights_punctual included, and the reader checks every index and byte range itself before
// reading (gltf_reader.h), so a bad file is one SceneError naming its glTF path, never a crash.
//
// The reading is in steps, one file each: the document and the files it reads
// (gltf_document.cpp), checked accessors (gltf_reader.cpp), materials (gltf_material.cpp),
// meshes (gltf_mesh.cpp), the node tree (gltf_node_tree.cpp), animation (gltf_animation.cpp),
// the camera (gltf_camera.cpp), lights (gltf_lights.cpp) and objects (gltf_objects.cpp).
#include "scene/gltf_scene.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>

#include "scene/gltf_animation.h"
#include "scene/gltf_camera.h"
#include "scene/gltf_document.h"
#include "scene/gltf_lights.h"
#include "scene/gltf_material.h"
#include "scene/gltf_mesh.h"
#include "scene/gltf_node_tree.h"
#include "scene/gltf_objects.h"
#include "scene/gltf_reader.h"

namespace tessera {

namespace fs = std::filesystem;

bool is_gltf_path(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".gltf" || ext == ".glb";
}

namespace {

// Per-frame keys for whatever moves: every frame is a key, so frames are exact.
void key_frames(const GltfAnimation& animation, const GltfCamera& camera,
                const std::vector<const NodeInstance*>& object_instance, const std::string& path, Scene* scene) {
  if (scene->animation.frame_count > 1) {
    const int frames = scene->animation.frame_count;
    const double fps = animation.fps();
    size_t keyed = 0;
    for (size_t oi = 0; oi < object_instance.size(); ++oi) keyed += animation.is_animated(*object_instance[oi]) ? 1 : 0;
    if ((keyed + 1) * size_t(frames) > 20000000) {
      throw SceneError(path + ": the animation needs more than 2e7 keys (" + std::to_string(keyed) + " moving objects x " +
                       std::to_string(frames) + " frames): lower --fps");
    }
    for (size_t oi = 0; oi < object_instance.size(); ++oi) {
      if (!animation.is_animated(*object_instance[oi])) continue;
      auto& keys = scene->animation.objects[int(oi)];
      for (int f = 0; f < frames; ++f) {
        TransformKey k;
        k.frame = f;
        k.transform.matrix = animation.world_at(*object_instance[oi], f / fps).affine();
        keys.push_back(k);
      }
    }
    if (animation.is_animated(camera.instance())) {
      for (int f = 0; f < frames; ++f) scene->animation.camera.push_back({f, camera.at(animation, f / fps)});
    }
  }
}

}  // namespace

Scene load_gltf_scene(const std::string& path, const SceneLoadOptions& options) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw SceneError(path + ": scene file not found");
  if (!fs::is_regular_file(path, ec)) throw SceneError(path + ": not a regular file");
  const uint64_t size = fs::file_size(path, ec);
  if (ec || size > options.max_file_bytes) {
    throw SceneError(path + ": larger than " + std::to_string(options.max_file_bytes) + " bytes");
  }
  std::ifstream in(path, std::ios::binary);
  std::string bytes(size_t(size), '\0');
  if (!in.read(bytes.data(), std::streamsize(size))) throw SceneError(path + ": cannot read the file");
  return parse_gltf_scene(bytes, path, options);
}

Scene parse_gltf_scene(const std::string& bytes, const std::string& path, const SceneLoadOptions& options) {
  const std::string file_name = fs::path(path).filename().string();

  std::vector<std::string> read;
  const tinygltf::Model model = read_gltf_document(bytes, path, options, &read);
  const GltfReader r(model, path);

  Scene scene;
  scene.path = path;
  scene.dependencies = read;
  std::sort(scene.dependencies.begin(), scene.dependencies.end());
  scene.dependencies.erase(std::unique(scene.dependencies.begin(), scene.dependencies.end()), scene.dependencies.end());

  const uint32_t default_material = read_gltf_materials(r, file_name, options.max_texture_pixels, &scene);
  read_gltf_meshes(r, path, default_material, &scene);
  const GltfNodeTree tree = read_gltf_node_tree(r, path, options.gltf);
  const GltfAnimation animation(r, tree, path, options.gltf);
  scene.animation.frame_count = animation.frame_count();
  const GltfCamera camera(r, tree, path, options.gltf, &scene);
  scene.camera = camera.at(animation, 0);
  read_gltf_lights(r, tree, animation, path, &scene.lights);
  const std::vector<const NodeInstance*> object_instance =
      place_gltf_objects(r, tree, animation, path, file_name, options, &scene);
  if (scene.objects.empty()) throw SceneError(path + ": " + tree.spath + " has no mesh with triangles");
  key_frames(animation, camera, object_instance, path, &scene);
  return scene;
}

}  // namespace tessera

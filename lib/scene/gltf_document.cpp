// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_document.h"

#include <filesystem>
#include <fstream>

#include "scene/scene_error.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// The files a glTF reads (see file_callbacks).
struct GltfFiles {
  fs::path root;  // confine_to, resolved; empty: anywhere
  uint64_t max_bytes;
  fs::path self;
  std::vector<std::string> read;  // relative to the scene's directory
  std::string refused;            // the first file refused
  bool allowed(const std::string& p) {
    if (root.empty()) return true;
    std::error_code e;
    const fs::path rel = fs::weakly_canonical(fs::absolute(p), e).lexically_relative(root);
    if (!e && !rel.empty() && *rel.begin() != "..") return true;
    if (refused.empty()) refused = p;
    return false;
  }
};

// Every file tinygltf reads goes through here: confined to the bundle, size-limited, recorded
// (a bundle carries the buffers and images of a .gltf). ExpandFilePath is the identity: the
// default one expands shell words in URIs.
tinygltf::FsCallbacks file_callbacks(GltfFiles* files) {
  tinygltf::FsCallbacks cb;
  cb.user_data = files;
  cb.ExpandFilePath = [](const std::string& p, void*) { return p; };
  cb.FileExists = [](const std::string& p, void* u) {
    std::error_code e;
    return static_cast<GltfFiles*>(u)->allowed(p) && fs::is_regular_file(p, e);
  };
  cb.ReadWholeFile = [](std::vector<unsigned char>* out, std::string* err, const std::string& p, void* u) {
    auto* f = static_cast<GltfFiles*>(u);
    if (!f->allowed(p)) {
      *err = "'" + p + "' is outside the scene bundle";
      return false;
    }
    std::error_code e;
    if (!fs::is_regular_file(p, e)) {
      *err = "'" + p + "' is not a regular file";
      return false;
    }
    const uint64_t size = fs::file_size(p, e);
    if (e || size > f->max_bytes) {
      *err = "'" + p + "' is larger than " + std::to_string(f->max_bytes) + " bytes";
      return false;
    }
    std::ifstream in(p, std::ios::binary);
    out->resize(size_t(size));
    if (!in.read(reinterpret_cast<char*>(out->data()), std::streamsize(size))) {
      *err = "cannot read '" + p + "'";
      return false;
    }
    const fs::path abs = fs::weakly_canonical(fs::absolute(p), e);
    if (abs != f->self) f->read.push_back(abs.lexically_relative(f->self.parent_path()).generic_string());
    return true;
  };
  cb.WriteWholeFile = [](std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    *err = "writing is not allowed";
    return false;
  };
  return cb;
}

}  // namespace

tinygltf::Model read_gltf_document(const std::string& bytes, const std::string& path, const SceneLoadOptions& options,
                                   std::vector<std::string>* read) {
  GltfFiles fsd{options.confine_to.empty() ? fs::path() : fs::weakly_canonical(fs::absolute(options.confine_to)),
        options.max_file_bytes, fs::weakly_canonical(fs::absolute(path)), {}, {}};
  tinygltf::TinyGLTF loader;
  loader.SetFsCallbacks(file_callbacks(&fsd));
  // Images are kept encoded here and decoded by gltf_texture.cpp (libpng/libjpeg), with limits.
  // An image in a bufferView is not touched here: tinygltf 2.7 passes its bytes without checking
  // the view against its buffer (the fuzzer's first find: a heap overflow), so the decoder reads
  // it from the buffer itself after checking the range.
  loader.SetImageLoader(
      [](tinygltf::Image* image, const int, std::string*, std::string*, int, int, const unsigned char* bytes, int size,
         void*) {
        if (image->bufferView < 0 && size > 0) image->image.assign(bytes, bytes + size);
        image->width = image->height = image->component = -1;
        return true;
      },
      nullptr);
  tinygltf::Model model;
  std::string err, warn;
  if (bytes.size() > options.max_file_bytes || bytes.size() > 0xFFFFFFFFu) throw SceneError(path + ": file too large");
  bool ok = false;
  const std::string base_dir = fs::path(path).parent_path().string();
  try {
    // Binary glTF by its magic, whatever the name says.
    ok = bytes.size() >= 4 && bytes.compare(0, 4, "glTF") == 0
             ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                           unsigned(bytes.size()), base_dir)
             : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), unsigned(bytes.size()), base_dir);
  } catch (const std::exception& e) {
    throw SceneError(path + ": invalid glTF: " + e.what());
  }
  if (!fsd.refused.empty()) {
    throw SceneError(path + ": refers to '" + fsd.refused +
                     "', which is outside the scene bundle (a glTF's buffers and images must lie in the bundle's directory)");
  }
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw SceneError(path + ": invalid glTF: " + (err.empty() ? std::string("cannot parse") : err));
  }
  *read = fsd.read;
  return model;
}

}  // namespace tessera

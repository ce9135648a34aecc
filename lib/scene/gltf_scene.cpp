// glTF 2.0 scenes through tinygltf (Debian's libtinygltf-dev 2.7), not assimp: assimp 5.2.5,
// which still loads meshes (mesh_loader.cpp), imports glTF cameras wrongly (its horizontal field
// of view is yfov x aspect, and the node's position is applied twice, once more as mPosition)
// and drops KHR_materials_emissive_strength. tinygltf hands over the document as written,
// KHR_lights_punctual included, and this file checks every index and byte range itself before
// reading, so a bad file is one SceneError naming its glTF path, never a crash.
#include "scene/gltf_scene.h"

#include <spdlog/spdlog.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <set>

#include "scene/gltf_texture.h"
#include "scene/scene_parser.h"

namespace tessera {

namespace fs = std::filesystem;

bool is_gltf_path(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".gltf" || ext == ".glb";
}

namespace {

// Column-major 4x4, as glTF writes matrices: m[4 * column + row].
struct Mat4 {
  std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double& at(int row, int col) { return m[size_t(4 * col + row)]; }
  double at(int row, int col) const { return m[size_t(4 * col + row)]; }
  Vec3d column(int c) const { return {at(0, c), at(1, c), at(2, c)}; }
};

Mat4 operator*(const Mat4& a, const Mat4& b) {
  Mat4 r;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      r.at(i, j) = a.at(i, 0) * b.at(0, j) + a.at(i, 1) * b.at(1, j) + a.at(i, 2) * b.at(2, j) + a.at(i, 3) * b.at(3, j);
    }
  }
  return r;
}

struct Trs {
  Vec3d t{0, 0, 0};
  std::array<double, 4> q{0, 0, 0, 1};  // x, y, z, w
  Vec3d s{1, 1, 1};
};

Mat4 trs_matrix(const Trs& v) {
  double x = v.q[0], y = v.q[1], z = v.q[2], w = v.q[3];
  const double n = std::sqrt(x * x + y * y + z * z + w * w);
  if (n > 0) { x /= n; y /= n; z /= n; w /= n; }  // animation outputs need not be unit
  Mat4 r;
  const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  const double S[3] = {v.s.x, v.s.y, v.s.z};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r.at(i, j) = R[i][j] * S[j];
  }
  r.at(0, 3) = v.t.x;
  r.at(1, 3) = v.t.y;
  r.at(2, 3) = v.t.z;
  return r;
}

std::array<double, 12> to_affine(const Mat4& m) {
  std::array<double, 12> a{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 4; ++j) a[size_t(4 * i + j)] = m.at(i, j);
  }
  return a;
}

// The files a glTF reads (see load_gltf_scene's callbacks).
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

// A node as the scene uses it: its local transform (animated or not) and the path from a root.
struct Instance {
  std::vector<int> chain;  // node indices, root first, this node last
};

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

  // Element i, component c of a view as a double (normalized integers scaled to [0, 1]).
  static double component(const View& v, size_t i, int c) {
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

  const tinygltf::Model& g_;
  std::string file_;
};

std::string idx(const char* array, size_t i) { return std::string(array) + "[" + std::to_string(i) + "]"; }

double ext_number(const tinygltf::ExtensionMap& exts, const char* ext, const char* key, double fallback) {
  auto it = exts.find(ext);
  if (it == exts.end() || !it->second.IsObject() || !it->second.Has(key)) return fallback;
  const tinygltf::Value& v = it->second.Get(key);
  return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
}

bool near(double a, double b) { return std::abs(a - b) <= 0.01; }

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
  if (gm.emissiveTexture.index >= 0) dropped.push_back("emissive texture (the emissive factor used alone)");
  if (pbr.metallicRoughnessTexture.index >= 0) dropped.push_back("metallic-roughness texture");
  if (gm.normalTexture.index >= 0) dropped.push_back("normal map");
  if (gm.alphaMode != "OPAQUE" && !gm.alphaMode.empty()) dropped.push_back("alpha " + gm.alphaMode + " (opaque)");
  for (const char* ext : {"KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_specular",
                          "KHR_materials_volume", "KHR_materials_iridescence", "KHR_materials_anisotropy"}) {
    if (gm.extensions.count(ext)) dropped.push_back(ext);
  }
  if (!dropped.empty()) {
    std::string list;
    for (const auto& d : dropped) list += (list.empty() ? "" : "; ") + d;
    spdlog::warn("{}: {} '{}': not in the Whitted model, nearest rule used: {}", file, path, gm.name, list);
  }
  return m;
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

  // Every file tinygltf reads goes through here: confined to the bundle, size-limited, recorded
  // (a bundle carries the buffers and images of a .gltf). ExpandFilePath is the identity: the
  // default one expands shell words in URIs.
  GltfFiles fsd{options.confine_to.empty() ? fs::path() : fs::weakly_canonical(fs::absolute(options.confine_to)),
        options.max_file_bytes, fs::weakly_canonical(fs::absolute(path)), {}, {}};
  tinygltf::FsCallbacks cb;
  cb.user_data = &fsd;
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

  tinygltf::TinyGLTF loader;
  loader.SetFsCallbacks(cb);
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
  const GltfReader r(model, path);

  Scene scene;
  scene.path = path;
  scene.dependencies = fsd.read;
  std::sort(scene.dependencies.begin(), scene.dependencies.end());
  scene.dependencies.erase(std::unique(scene.dependencies.begin(), scene.dependencies.end()), scene.dependencies.end());

  // Textures: decoded once per (image, sampler) on first use by a material.
  TextureDecoder decoder(model, path, options.max_texture_pixels, &scene.textures);
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
    scene.materials.push_back(map_material(r, i, file_name, texture_of));
  }
  const uint32_t default_material = uint32_t(scene.materials.size());
  scene.materials.push_back(Material{.name = file_name + ":default"});

  // Meshes: one Scene mesh per glTF mesh (all its triangle primitives), shared by every node
  // that uses it: an instanced mesh is loaded once.
  size_t dropped_other_modes = 0, dropped_degenerate = 0;
  std::string first_morphed;  // glTF path of the first primitive with morph targets
  for (size_t mi = 0; mi < model.meshes.size(); ++mi) {
    Mesh mesh;
    const auto& gmesh = model.meshes[mi];
    for (size_t pi = 0; pi < gmesh.primitives.size(); ++pi) {
      const auto& prim = gmesh.primitives[pi];
      const std::string ppath = idx("meshes", mi) + "." + idx("primitives", pi);
      if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) {
        ++dropped_other_modes;  // points, lines, strips and fans
        continue;
      }
      if (!prim.targets.empty() && first_morphed.empty()) first_morphed = ppath + ".targets";
      auto pos_it = prim.attributes.find("POSITION");
      if (pos_it == prim.attributes.end()) r.fail(ppath + ".attributes", "has no POSITION");
      const auto pos = r.accessor(pos_it->second, ppath + ".attributes.POSITION", {TINYGLTF_TYPE_VEC3},
                                  {TINYGLTF_COMPONENT_TYPE_FLOAT});
      const uint32_t base = uint32_t(mesh.positions.size());
      if (mesh.positions.size() + pos.count > (uint64_t(1) << 31)) r.fail(ppath, "too many vertices");
      for (size_t v = 0; v < pos.count; ++v) {
        mesh.positions.push_back(Vec3f(float(GltfReader::component(pos, v, 0)), float(GltfReader::component(pos, v, 1)),
                                       float(GltfReader::component(pos, v, 2))));
      }
      if (prim.material >= 0 && size_t(prim.material) >= model.materials.size()) {
        r.fail(ppath + ".material", "material " + std::to_string(prim.material) + " does not exist");
      }
      const uint32_t mat = prim.material >= 0 ? uint32_t(prim.material) : default_material;
      // Texture coordinates of the set the material reads (TEXCOORD_n), when it has a texture.
      const Material& material = scene.materials[mat];
      if (material.albedo_texture >= 0) {
        const std::string set = "TEXCOORD_" + std::to_string(material.uv_set);
        auto uv_it = prim.attributes.find(set);
        if (uv_it == prim.attributes.end()) r.fail(ppath + ".attributes", "has no " + set + " for its material's texture");
        const auto uv = r.accessor(uv_it->second, ppath + ".attributes." + set, {TINYGLTF_TYPE_VEC2},
                                   {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                    TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
        if (uv.count != pos.count) r.fail(ppath + ".attributes." + set, "count differs from POSITION's");
        mesh.uvs.resize(2 * size_t(base), 0.0f);
        for (size_t v = 0; v < uv.count; ++v) {
          mesh.uvs.push_back(float(GltfReader::component(uv, v, 0)));
          mesh.uvs.push_back(float(GltfReader::component(uv, v, 1)));
        }
      } else if (!mesh.uvs.empty()) {
        mesh.uvs.resize(2 * mesh.positions.size(), 0.0f);
      }
      // Vertex normals: interpolated shading normals (render/shading_normal.h). A zero or
      // non-finite one is kept as zero: its triangles shade flat.
      if (auto n_it = prim.attributes.find("NORMAL"); n_it != prim.attributes.end()) {
        const auto nrm = r.accessor(n_it->second, ppath + ".attributes.NORMAL", {TINYGLTF_TYPE_VEC3},
                                    {TINYGLTF_COMPONENT_TYPE_FLOAT});
        if (nrm.count != pos.count) r.fail(ppath + ".attributes.NORMAL", "count differs from POSITION's");
        mesh.normals.resize(size_t(base), Vec3f(0.0f));
        for (size_t v = 0; v < nrm.count; ++v) {
          const Vec3f n(float(GltfReader::component(nrm, v, 0)), float(GltfReader::component(nrm, v, 1)),
                        float(GltfReader::component(nrm, v, 2)));
          mesh.normals.push_back(is_finite(n) ? n : Vec3f(0.0f));
        }
      } else if (!mesh.normals.empty()) {
        mesh.normals.resize(mesh.positions.size(), Vec3f(0.0f));
      }
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
      for (size_t k = 0; k < tri.size(); k += 3) {
        const Vec3d a(mesh.positions[base + tri[k]]), b(mesh.positions[base + tri[k + 1]]),
            c(mesh.positions[base + tri[k + 2]]);
        if (!is_finite(a) || !is_finite(b) || !is_finite(c) || dot(cross(b - a, c - a), cross(b - a, c - a)) == 0.0) {
          ++dropped_degenerate;  // NaN/Inf or zero area: no surface
          continue;
        }
        mesh.indices.insert(mesh.indices.end(), {base + tri[k], base + tri[k + 1], base + tri[k + 2]});
        mesh.material_ids.push_back(mat);
      }
    }
    for (auto& p : mesh.positions) {
      if (!is_finite(p)) p = Vec3f(0.0f);  // unreferenced now; must not reach Embree's bounds
    }
    scene.meshes.push_back(std::move(mesh));
  }
  if (dropped_other_modes) {
    spdlog::warn("{}: {} primitives that are not triangles (points, lines, strips, fans) ignored", path,
                 dropped_other_modes);
  }
  if (!first_morphed.empty()) {
    spdlog::warn("{}: {}: morph targets are not supported: meshes render in their base shape, and animations of "
                 "their weights are ignored", path, first_morphed);
  }
  if (dropped_degenerate) {
    spdlog::warn("{}: dropped {} triangles with a NaN/Inf vertex or zero area", path, dropped_degenerate);
  }

  // The scene to show.
  if (model.scenes.empty()) r.fail("scenes", "the file has no scene");
  int si = options.gltf.scene_index >= 0 ? options.gltf.scene_index : (model.defaultScene >= 0 ? model.defaultScene : 0);
  if (options.gltf.scene_index < -1 || si < 0 || size_t(si) >= model.scenes.size()) {
    const std::string which = options.gltf.scene_index == -1 ? "scene " : "--scene-index ";
    throw SceneError(path + ": " + which + std::to_string(options.gltf.scene_index == -1 ? si : options.gltf.scene_index) +
                     ": must be in [0, " + std::to_string(model.scenes.size() - 1) + "] (the file's scenes)");
  }
  const std::string spath = idx("scenes", size_t(si));

  // Local transforms of every node at rest (animations replace parts of them per frame).
  std::vector<Trs> rest(model.nodes.size());
  std::vector<std::optional<Mat4>> rest_matrix(model.nodes.size());
  for (size_t n = 0; n < model.nodes.size(); ++n) {
    const auto& node = model.nodes[n];
    const std::string np = idx("nodes", n);
    auto finite_all = [&](const std::vector<double>& v, size_t want, const char* field) {
      if (v.empty()) return false;
      if (v.size() != want) r.fail(np + "." + field, "must have " + std::to_string(want) + " numbers");
      for (double x : v) {
        if (!std::isfinite(x) || std::abs(x) > 1e15) r.fail(np + "." + field, "must be finite numbers within +-1e15");
      }
      return true;
    };
    if (finite_all(node.matrix, 16, "matrix")) {
      Mat4 m;
      std::copy(node.matrix.begin(), node.matrix.end(), m.m.begin());
      rest_matrix[n] = m;
    }
    if (finite_all(node.translation, 3, "translation")) rest[n].t = {node.translation[0], node.translation[1], node.translation[2]};
    if (finite_all(node.rotation, 4, "rotation")) {
      rest[n].q = {node.rotation[0], node.rotation[1], node.rotation[2], node.rotation[3]};
      if (!(std::abs(rest[n].q[0]) + std::abs(rest[n].q[1]) + std::abs(rest[n].q[2]) + std::abs(rest[n].q[3]) > 0)) {
        r.fail(np + ".rotation", "must not be the zero quaternion");
      }
    }
    if (finite_all(node.scale, 3, "scale")) rest[n].s = {node.scale[0], node.scale[1], node.scale[2]};
  }

  // Walk the scene: every path from a root to a node is an instance. A node met again on its own
  // path is a cycle (glTF forbids it); the walk is bounded so a DAG cannot explode.
  std::vector<Instance> instances;
  constexpr size_t kMaxInstances = 1000000;
  std::vector<int> chain;
  std::function<void(int, const std::string&)> walk = [&](int n, const std::string& where) {
    if (n < 0 || size_t(n) >= model.nodes.size()) r.fail(where, "node " + std::to_string(n) + " does not exist");
    if (std::find(chain.begin(), chain.end(), n) != chain.end()) {
      r.fail(where, "node " + std::to_string(n) + " is its own ancestor (the hierarchy has a cycle)");
    }
    if (chain.size() >= 256) r.fail(where, "the node hierarchy is deeper than 256");
    if (instances.size() >= kMaxInstances) r.fail(where, "more than 1000000 node instances");
    chain.push_back(n);
    instances.push_back({chain});
    const auto& children = model.nodes[size_t(n)].children;
    for (size_t c = 0; c < children.size(); ++c) walk(children[c], idx("nodes", size_t(n)) + "." + idx("children", c));
    chain.pop_back();
  };
  const auto& roots = model.scenes[size_t(si)].nodes;
  for (size_t k = 0; k < roots.size(); ++k) walk(roots[k], spath + "." + idx("nodes", k));

  // Animation: every channel of every animation on one timeline, frame F at time F / fps.
  struct Channel { int node; std::string target; std::vector<double> times; std::vector<double> values; int n; std::string interp; };
  std::vector<Channel> channels;
  double duration = 0;
  for (size_t ai = 0; ai < model.animations.size(); ++ai) {
    const auto& anim = model.animations[ai];
    for (size_t ci = 0; ci < anim.channels.size(); ++ci) {
      const auto& ch = anim.channels[ci];
      const std::string cp = idx("animations", ai) + "." + idx("channels", ci);
      if (ch.target_path == "weights") continue;  // morph targets: not supported, geometry unchanged
      if (ch.target_path != "translation" && ch.target_path != "rotation" && ch.target_path != "scale") {
        r.fail(cp + ".target.path", "must be translation, rotation, scale or weights");
      }
      if (ch.target_node < 0 || size_t(ch.target_node) >= model.nodes.size()) r.fail(cp + ".target.node", "does not exist");
      if (ch.sampler < 0 || size_t(ch.sampler) >= anim.samplers.size()) r.fail(cp + ".sampler", "does not exist");
      const auto& smp = anim.samplers[size_t(ch.sampler)];
      const std::string sp = idx("animations", ai) + "." + idx("samplers", size_t(ch.sampler));
      Channel c{ch.target_node, ch.target_path, {}, {}, ch.target_path == "rotation" ? 4 : 3, smp.interpolation};
      if (c.interp != "LINEAR" && c.interp != "STEP" && c.interp != "CUBICSPLINE") r.fail(sp + ".interpolation", "unknown");
      const auto in = r.accessor(smp.input, sp + ".input", {TINYGLTF_TYPE_SCALAR}, {TINYGLTF_COMPONENT_TYPE_FLOAT});
      const auto out = r.accessor(smp.output, sp + ".output", {c.n == 4 ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3},
                                  {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                   TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
      const size_t per_key = c.interp == "CUBICSPLINE" ? 3 : 1;
      if (out.count != in.count * per_key) r.fail(sp + ".output", "count does not match the input's keyframes");
      for (size_t k = 0; k < in.count; ++k) {
        const double t = GltfReader::component(in, k, 0);
        if (!std::isfinite(t) || t < 0 || (k > 0 && t <= c.times.back())) {
          r.fail(sp + ".input", "keyframe times must be finite, >= 0 and strictly increasing");
        }
        c.times.push_back(t);
      }
      for (size_t k = 0; k < out.count; ++k) {
        for (int j = 0; j < c.n; ++j) {
          const double v = GltfReader::component(out, k, j);
          if (!std::isfinite(v) || std::abs(v) > 1e15) r.fail(sp + ".output", "values must be finite within +-1e15");
          c.values.push_back(v);
        }
      }
      duration = std::max(duration, c.times.back());
      channels.push_back(std::move(c));
    }
  }
  const double fps = options.gltf.fps;
  if (!(fps > 0 && fps <= GltfOptions::kMaxFps)) {
    throw SceneError(path + ": --fps: must be in (0, " + std::to_string(int(GltfOptions::kMaxFps)) + "], got " + std::to_string(fps));
  }
  const double frames_d = std::floor(duration * fps + 1e-9) + 1;
  if (frames_d > SceneLimits::kMaxFrames) {
    throw SceneError(path + ": the animation lasts " + std::to_string(duration) + " s: more than " +
                     std::to_string(SceneLimits::kMaxFrames) + " frames at --fps " + std::to_string(fps));
  }
  scene.animation.frame_count = channels.empty() ? 1 : int(frames_d);

  // The local transform of node n at time t (rest pose where no channel drives it).
  auto local_at = [&](int n, double t, bool animated) -> Mat4 {
    if (!animated) return rest_matrix[size_t(n)] ? *rest_matrix[size_t(n)] : trs_matrix(rest[size_t(n)]);
    Trs v = rest[size_t(n)];
    for (const Channel& c : channels) {
      if (c.node != n) continue;
      const size_t nk = c.times.size();
      const bool cubic = c.interp == "CUBICSPLINE";
      auto value = [&](size_t key, int j) { return c.values[(cubic ? 3 * key + 1 : key) * size_t(c.n) + size_t(j)]; };
      double out[4];
      size_t k = 0;
      while (k + 1 < nk && c.times[k + 1] <= t) ++k;
      if (t <= c.times.front() || k + 1 >= nk || c.interp == "STEP") {
        const size_t key = t <= c.times.front() ? 0 : k;
        for (int j = 0; j < c.n; ++j) out[j] = value(key, j);
      } else {
        const double dt = c.times[k + 1] - c.times[k], s = (t - c.times[k]) / dt;
        if (cubic) {
          // Hermite spline with the glTF tangents (out-tangent of k, in-tangent of k + 1).
          const double s2 = s * s, s3 = s2 * s;
          for (int j = 0; j < c.n; ++j) {
            const double b0 = c.values[(3 * k + 2) * size_t(c.n) + size_t(j)];
            const double a1 = c.values[(3 * (k + 1)) * size_t(c.n) + size_t(j)];
            out[j] = (2 * s3 - 3 * s2 + 1) * value(k, j) + (s3 - 2 * s2 + s) * dt * b0 +
                     (-2 * s3 + 3 * s2) * value(k + 1, j) + (s3 - s2) * dt * a1;
          }
        } else if (c.n == 4) {
          // Spherical linear interpolation along the shorter arc, as the glTF spec asks.
          double a[4], b[4], d = 0;
          for (int j = 0; j < 4; ++j) { a[j] = value(k, j); b[j] = value(k + 1, j); d += a[j] * b[j]; }
          if (d < 0) { for (double& x : b) x = -x; d = -d; }
          if (d > 0.9995) {
            for (int j = 0; j < 4; ++j) out[j] = a[j] + s * (b[j] - a[j]);
          } else {
            const double th = std::acos(std::min(d, 1.0)), sn = std::sin(th);
            const double wa = std::sin((1 - s) * th) / sn, wb = std::sin(s * th) / sn;
            for (int j = 0; j < 4; ++j) out[j] = wa * a[j] + wb * b[j];
          }
        } else {
          for (int j = 0; j < c.n; ++j) out[j] = value(k, j) * (1 - s) + value(k + 1, j) * s;
        }
      }
      if (c.target == "translation") v.t = {out[0], out[1], out[2]};
      else if (c.target == "scale") v.s = {out[0], out[1], out[2]};
      else v.q = {out[0], out[1], out[2], out[3]};
    }
    return trs_matrix(v);
  };
  std::vector<bool> node_animated(model.nodes.size(), false);
  for (const Channel& c : channels) {
    node_animated[size_t(c.node)] = true;
    if (rest_matrix[size_t(c.node)]) r.fail(idx("nodes", size_t(c.node)), "is animated but has a matrix (glTF requires TRS)");
  }
  auto world_at = [&](const Instance& inst, double t) {
    Mat4 m;
    for (int n : inst.chain) m = m * local_at(n, t, node_animated[size_t(n)]);
    return m;
  };
  auto is_animated = [&](const Instance& inst) {
    return std::any_of(inst.chain.begin(), inst.chain.end(), [&](int n) { return node_animated[size_t(n)]; });
  };

  // Camera: the first in the walk, or the one named (camera name or node name).
  const Instance* cam = nullptr;
  std::string cam_names;
  for (const Instance& inst : instances) {
    const auto& node = model.nodes[size_t(inst.chain.back())];
    if (node.camera < 0) continue;
    if (size_t(node.camera) >= model.cameras.size()) {
      r.fail(idx("nodes", size_t(inst.chain.back())) + ".camera", "camera " + std::to_string(node.camera) + " does not exist");
    }
    const auto& c = model.cameras[size_t(node.camera)];
    cam_names += (cam_names.empty() ? "'" : ", '") + (c.name.empty() ? node.name : c.name) + "'";
    if (!cam && (options.gltf.camera.empty() || options.gltf.camera == c.name || options.gltf.camera == node.name)) {
      cam = &inst;
    }
  }
  if (!cam) {
    if (!options.gltf.camera.empty()) {
      throw SceneError(path + ": --camera '" + options.gltf.camera + "': no camera or camera node of " + spath +
                       " has that name (cameras: " + (cam_names.empty() ? "none" : cam_names) + ")");
    }
    throw SceneError(path + ": " + spath + " has no camera (export with cameras included: Blender's glTF "
                     "exporter, Include > Data > Cameras)");
  }
  const int cam_index = model.nodes[size_t(cam->chain.back())].camera;
  const auto& gcam = model.cameras[size_t(cam_index)];
  const std::string cpath = idx("cameras", size_t(cam_index));
  if (gcam.type != "perspective") {
    r.fail(cpath + ".type", "'" + gcam.type + "' cameras are not supported: Tessera renders perspective cameras only");
  }
  const double yfov = gcam.perspective.yfov;
  if (!(yfov > 0 && yfov < std::numbers::pi)) r.fail(cpath + ".perspective.yfov", "must be in (0, pi) radians");
  if (gcam.perspective.aspectRatio != 0) {
    const double a = gcam.perspective.aspectRatio;
    if (!(a > 1e-4 && a < 1e4)) r.fail(cpath + ".perspective.aspectRatio", "must be in (1e-4, 1e4)");
    scene.camera_aspect = a;
    scene.image.height = std::clamp(int(std::lround(scene.image.width / a)), 1, SceneLimits::kMaxResolution);
  }
  auto camera_at = [&](double t) {
    const Mat4 m = world_at(*cam, t);
    CameraDesc c;
    c.form = CameraDesc::Form::kLookAt;
    // glTF cameras look down their local -Z with +Y up; scale is ignored (normalized).
    c.position = m.column(3);
    const Vec3d back = m.column(2), up = m.column(1);
    if (!(length(back) > 0) || !(length(up) > 0) || length(cross(normalize(back), normalize(up))) < 1e-9) {
      r.fail(idx("nodes", size_t(cam->chain.back())), "the camera's transform is degenerate");
    }
    c.look_at = c.position - normalize(back);
    c.up = normalize(up);
    c.vfov_deg = yfov * 180.0 / std::numbers::pi;
    return c;
  };
  scene.camera = camera_at(0);

  // Lights (KHR_lights_punctual), in radiometric units: docs/scene-format.md. Lights take the
  // pose of frame 0.
  for (const Instance& inst : instances) {
    const size_t n = size_t(inst.chain.back());
    auto it = model.nodes[n].extensions.find("KHR_lights_punctual");
    if (it == model.nodes[n].extensions.end()) continue;
    const std::string lp = idx("nodes", n) + ".extensions.KHR_lights_punctual.light";
    if (!it->second.IsObject() || !it->second.Has("light") || !it->second.Get("light").IsInt()) r.fail(lp, "must be a light index");
    const int li = it->second.Get("light").GetNumberAsInt();
    if (li < 0 || size_t(li) >= model.lights.size()) r.fail(lp, "light " + std::to_string(li) + " does not exist");
    const auto& gl = model.lights[size_t(li)];
    const std::string gp = "extensions.KHR_lights_punctual." + idx("lights", size_t(li));
    if (is_animated(inst)) spdlog::warn("{}: {}: animated lights keep their frame-0 pose", path, gp);
    Rgb color(1.0f);
    if (!gl.color.empty()) {
      if (gl.color.size() != 3) r.fail(gp + ".color", "must have 3 numbers");
      for (int c = 0; c < 3; ++c) {
        if (!(gl.color[size_t(c)] >= 0 && gl.color[size_t(c)] <= 1e6)) r.fail(gp + ".color", "must be >= 0");
        color[c] = float(gl.color[size_t(c)]);
      }
    }
    if (!(gl.intensity >= 0 && gl.intensity <= 1e20)) r.fail(gp + ".intensity", "must be in [0, 1e20]");
    // 683 lm/W: candela -> W/sr and lux -> W/m^2, the inverse of Blender's exporter (docs).
    const Rgb radiometric = color * float(gl.intensity / 683.0);
    const Mat4 m = world_at(inst, 0);
    Light L;
    const Vec3d axis = m.column(2);
    if (gl.type == "point" || gl.type == "spot") {
      L.type = gl.type == "point" ? Light::Type::kPoint : Light::Type::kSpot;
      L.position = m.column(3);
      L.intensity = radiometric;
    } else if (gl.type == "directional") {
      L.type = Light::Type::kDirectional;
      L.irradiance = radiometric;
    } else {
      r.fail(gp + ".type", "must be point, spot or directional, got '" + gl.type + "'");
    }
    if (L.type != Light::Type::kPoint) {
      if (!(length(axis) > 0)) r.fail(idx("nodes", n), "the light's transform is degenerate");
      L.direction = -normalize(axis);  // lights shine down their local -Z
    }
    if (L.type == Light::Type::kSpot) {
      L.inner_cone_rad = gl.spot.innerConeAngle;
      L.outer_cone_rad = gl.spot.outerConeAngle;
      if (!(L.outer_cone_rad > 0 && L.outer_cone_rad <= std::numbers::pi / 2)) r.fail(gp + ".spot.outerConeAngle", "must be in (0, pi/2]");
      if (!(L.inner_cone_rad >= 0 && L.inner_cone_rad < L.outer_cone_rad)) {
        r.fail(gp + ".spot.innerConeAngle", "must be in [0, outerConeAngle)");
      }
    }
    if (gl.range > 0) spdlog::warn("{}: {}: range {} ignored (light falls off as 1/r^2 without a cutoff)", path, gp, gl.range);
    scene.lights.push_back(L);
  }

  // Objects: one per mesh instance, sharing the mesh.
  uint64_t primitives = 0;
  std::vector<const Instance*> object_instance;
  std::string first_skinned;  // glTF path of the first skinned mesh node shown
  size_t skinned = 0;
  for (const Instance& inst : instances) {
    const auto& node = model.nodes[size_t(inst.chain.back())];
    if (node.mesh < 0) continue;
    if (node.skin >= 0 && skinned++ == 0) first_skinned = idx("nodes", size_t(inst.chain.back())) + ".skin";
    if (size_t(node.mesh) >= model.meshes.size()) {
      r.fail(idx("nodes", size_t(inst.chain.back())) + ".mesh", "mesh " + std::to_string(node.mesh) + " does not exist");
    }
    if (scene.meshes[size_t(node.mesh)].triangle_count() == 0) continue;
    primitives += scene.meshes[size_t(node.mesh)].triangle_count();
    if (options.max_primitives > 0 && primitives > options.max_primitives) {
      r.fail(idx("nodes", size_t(inst.chain.back())), "the scene has more than " + std::to_string(options.max_primitives) +
                                                           " primitives (triangles of every mesh instance): limit max_primitives");
    }
    SceneObject o;
    o.type = SceneObject::Type::kMesh;
    o.name = node.name;
    o.mesh = node.mesh;
    o.file = file_name;
    o.transform.matrix = to_affine(world_at(inst, 0));
    scene.objects.push_back(std::move(o));
    object_instance.push_back(&inst);
  }
  // Skins are not evaluated: a skinned mesh renders in its bind pose (its vertices as stored,
  // placed by its node), never silently.
  if (skinned) {
    spdlog::warn("{}: {}: skins are not supported: {} skinned mesh instance{} render{} in the bind pose, "
                 "without the joints' transforms or animation (apply the armature before export to pose them)",
                 path, first_skinned, skinned, skinned == 1 ? "" : "s", skinned == 1 ? "s" : "");
  }

  if (scene.objects.empty()) throw SceneError(path + ": " + spath + " has no mesh with triangles");

  // Per-frame keys for whatever moves: every frame is a key, so frames are exact.
  if (scene.animation.frame_count > 1) {
    const int frames = scene.animation.frame_count;
    size_t keyed = 0;
    for (size_t oi = 0; oi < object_instance.size(); ++oi) keyed += is_animated(*object_instance[oi]) ? 1 : 0;
    if ((keyed + 1) * size_t(frames) > 20000000) {
      throw SceneError(path + ": the animation needs more than 2e7 keys (" + std::to_string(keyed) + " moving objects x " +
                       std::to_string(frames) + " frames): lower --fps");
    }
    for (size_t oi = 0; oi < object_instance.size(); ++oi) {
      if (!is_animated(*object_instance[oi])) continue;
      auto& keys = scene.animation.objects[int(oi)];
      for (int f = 0; f < frames; ++f) {
        TransformKey k;
        k.frame = f;
        k.transform.matrix = to_affine(world_at(*object_instance[oi], f / fps));
        keys.push_back(k);
      }
    }
    if (is_animated(*cam)) {
      for (int f = 0; f < frames; ++f) scene.animation.camera.push_back({f, camera_at(f / fps)});
    }
  }
  return scene;
}

}  // namespace tessera

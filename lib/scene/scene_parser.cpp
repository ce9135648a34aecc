// SPDX-License-Identifier: Apache-2.0
#include "scene/scene_parser.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <functional>
#include <numbers>
#include <sstream>

#include "scene/gltf_scene.h"
#include "scene/json_reader.h"
#include "scene/mesh_loader.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

constexpr double kMaxCoordinate = 1e15;  // beyond this doubles lose integer precision; floats are hopeless
constexpr double kMaxRadiance = 1e20;    // HDR floats: 160 is legal, Inf is not

void check_coord(const JsonReader& r, const Vec3d& v) {
  if (std::abs(v.x) > kMaxCoordinate || std::abs(v.y) > kMaxCoordinate || std::abs(v.z) > kMaxCoordinate) {
    r.fail("coordinates must be within +-1e15");
  }
}

Vec3d read_point(const JsonReader& r) {
  const Vec3d v = r.vec3();
  check_coord(r, v);
  return v;
}

Vec3d read_direction(const JsonReader& r) {
  const Vec3d v = r.vec3();
  const double len = length(v);
  if (!(len > 1e-30) || !std::isfinite(len)) r.fail("must be a non-zero direction vector");
  return v / len;
}

CameraDesc read_camera_fields(const JsonReader& r, const CameraDesc* base) {
  CameraDesc c = base ? *base : CameraDesc{};
  const bool look = r.has("position") || r.has("look_at") || r.has("vfov_deg") || r.has("up");
  const bool screen = r.has("eye") || r.has("p0") || r.has("p1") || r.has("p2");
  if (look && screen) r.fail("use either position/look_at/up/vfov_deg or eye/p0/p1/p2, not both");
  if (!base && !look && !screen) r.fail("needs position/look_at/up/vfov_deg or eye/p0/p1/p2");
  if (look || (!screen && c.form == CameraDesc::Form::kLookAt)) {
    if (base && c.form != CameraDesc::Form::kLookAt && look) {
      r.fail("keyframes must use the same camera form as the scene's camera (eye/p0/p1/p2)");
    }
    c.form = CameraDesc::Form::kLookAt;
    if (auto v = r.find("position")) c.position = read_point(*v); else if (!base) r.at("position");
    if (auto v = r.find("look_at")) c.look_at = read_point(*v); else if (!base) r.at("look_at");
    if (auto v = r.find("up")) c.up = read_direction(*v);
    if (auto v = r.find("vfov_deg")) c.vfov_deg = v->number_in(0.0, 180.0, true);
    if (c.vfov_deg >= 180.0) r.at("vfov_deg").fail("must be in (0, 180)");
    const Vec3d fwd = c.look_at - c.position;
    if (!(length(fwd) > 0)) r.fail("look_at must differ from position");
    if (length(cross(normalize(fwd), c.up)) < 1e-9) r.fail("up must not be parallel to the view direction");
  } else {
    if (base && c.form != CameraDesc::Form::kScreenPlane) {
      r.fail("keyframes must use the same camera form as the scene's camera (position/look_at)");
    }
    c.form = CameraDesc::Form::kScreenPlane;
    for (const char* k : {"eye", "p0", "p1", "p2"}) {
      auto v = r.find(k);
      if (!v && !base) r.at(k);
      if (!v) continue;
      const Vec3d p = read_point(*v);
      if (std::string(k) == "eye") c.eye = p;
      else if (std::string(k) == "p0") c.p0 = p;
      else if (std::string(k) == "p1") c.p1 = p;
      else c.p2 = p;
    }
    const Vec3d n = cross(c.p1 - c.p0, c.p2 - c.p0);
    if (!(length(n) > 0)) r.fail("p0, p1, p2 must span a screen plane (not collinear)");
    if (std::abs(dot(n, c.p0 - c.eye)) <= 1e-12 * length(n) * length(c.p0 - c.eye)) {
      r.fail("eye must not lie in the screen plane p0, p1, p2");
    }
  }
  return c;
}

TransformDesc read_transform(const JsonReader& r, const TransformDesc* base) {
  TransformDesc t = base ? *base : TransformDesc{};
  if (auto v = r.find("translate")) t.translate = read_point(*v);
  if (auto v = r.find("rotate")) t.rotate_deg = v->vec3();
  if (auto v = r.find("scale")) {
    if (v->value().is_number()) {
      t.scale = Vec3d(v->number());
    } else {
      t.scale = v->vec3();
    }
    if (t.scale.x == 0 || t.scale.y == 0 || t.scale.z == 0) v->fail("scale must be non-zero on every axis");
  }
  return t;
}

Material read_material(const JsonReader& r, const std::string& name) {
  Material m;
  m.name = name;
  const std::string type = r.at("type").one_of({"diffuse", "mirror", "glass"});
  if (type == "diffuse") {
    m.type = Material::Type::kDiffuse;
    if (auto v = r.find("albedo")) m.albedo = v->rgb(1.0);
    if (auto c = r.find("checker")) {
      m.checker = true;
      if (auto v = c->find("albedo2")) m.albedo2 = v->rgb(1.0);
      if (auto v = c->find("scale")) m.checker_scale = v->number_in(0.0, kMaxCoordinate, true);
      c->reject_unknown();
    }
  } else if (type == "mirror") {
    m.type = Material::Type::kMirror;
    if (auto v = r.find("reflectance")) m.reflectance = v->rgb(1.0);
  } else {
    m.type = Material::Type::kGlass;
    if (auto v = r.find("ior")) m.ior = v->number_in(1.0, 10.0);
    if (auto v = r.find("transmittance")) m.transmittance = v->rgb(1.0);
  }
  if (auto v = r.find("emission")) m.emission = v->rgb(kMaxRadiance);
  r.reject_unknown();
  return m;
}

SceneObject read_object(const JsonReader& r, const std::map<std::string, int>& materials,
                        std::vector<std::string>* exclude) {
  SceneObject o;
  const std::string type = r.at("type").one_of({"sphere", "plane", "mesh"});
  if (auto v = r.find("name")) o.name = v->string();
  if (auto v = r.find("material")) {
    const std::string name = v->string();
    auto it = materials.find(name);
    if (it == materials.end()) {
      std::string known;
      for (const auto& [k, _] : materials) known += (known.empty() ? "" : ", ") + ("'" + k + "'");
      v->fail("unknown material '" + name + "' (defined: " + (known.empty() ? "none" : known) + ")");
    }
    o.material = it->second;
  } else if (type != "mesh") {
    r.at("material");
  }
  if (auto v = r.find("transform")) {
    o.transform = read_transform(*v, nullptr);
    v->reject_unknown();
  }
  if (type == "sphere") {
    o.type = SceneObject::Type::kSphere;
    o.center = read_point(r.at("center"));
    o.radius = r.at("radius").number_in(0.0, kMaxCoordinate, true);
    const Vec3d s = o.transform.scale;
    if (s.x != s.y || s.y != s.z) r.at("transform").fail("a sphere takes a uniform scale only");
  } else if (type == "plane") {
    o.type = SceneObject::Type::kPlane;
    o.point = read_point(r.at("point"));
    o.normal = read_direction(r.at("normal"));
  } else {
    o.type = SceneObject::Type::kMesh;
    o.file = r.at("file").string();
    if (o.file.empty()) r.at("file").fail("must name a mesh file");
    if (auto v = r.find("exclude")) {
      for (const auto& e : v->array()) exclude->push_back(e.string());
    }
  }
  r.reject_unknown();
  return o;
}

std::string line_col(const std::string& text, size_t byte) {
  size_t line = 1, col = 1;
  for (size_t i = 0; i < byte && i < text.size(); ++i) {
    if (text[i] == '\n') { ++line; col = 1; } else { ++col; }
  }
  return std::to_string(line) + ":" + std::to_string(col);
}

}  // namespace

std::optional<SamplerKind> sampler_from_name(const std::string& name) {
  // "stratified" was the name of the default sampler before it became progressive; it keeps
  // naming the default so existing scene files and scripts mean what they meant.
  if (name == "sobol" || name == "stratified") return SamplerKind::kSobol;
  if (name == "cmj") return SamplerKind::kCmj;
  if (name == "independent") return SamplerKind::kIndependent;
  if (name == "center") return SamplerKind::kCenter;
  if (name == "lattice") return SamplerKind::kLattice;
  return std::nullopt;
}

const char* sampler_name(SamplerKind kind) {
  switch (kind) {
    case SamplerKind::kSobol: return "sobol";
    case SamplerKind::kCmj: return "cmj";
    case SamplerKind::kIndependent: return "independent";
    case SamplerKind::kCenter: return "center";
    case SamplerKind::kLattice: return "lattice";
  }
  return "?";
}

const char* sampler_names() { return "sobol, stratified, cmj, independent, center, lattice"; }

namespace {

// The adaptive settings' rules, shared by the scene file and the overrides; `name` spells each
// field as the caller's user knows it (a JSON path or a command-line flag).
void check_adaptive(const ImageSettings& s, const std::function<std::string(const char*)>& name) {
  if (s.sampler == SamplerKind::kLattice && !s.frame_target()) {
    throw SceneError(name("sampler") + " lattice renders to a frame target only: give " + name("target_rmse") +
                     " too, or one of the samplers sobol, cmj, independent, center");
  }
  if (!s.adaptive()) return;
  const char* field = s.frame_target() ? "target_rmse" : "block_rmse";
  if (s.target_rmse > 0 && s.block_rmse > 0) {
    throw SceneError(name("target_rmse") + " and " + name("block_rmse") +
                     " conflict: a render is held to the frame's error or to every block's, not both");
  }
  if (s.first_spp() > s.max_spp) {
    throw SceneError(name("min_spp") + " (" + std::to_string(s.first_spp()) + (s.min_spp > 0 ? "" : ", its default") +
                     ") must not exceed " + name("max_spp") + " (" + std::to_string(s.max_spp) + ")");
  }
  if (s.sampler == SamplerKind::kCmj || s.sampler == SamplerKind::kCenter) {
    throw SceneError(name(field) + " needs a progressive sampler with an error estimate (sobol or "
                     "independent), not " + sampler_name(s.sampler) +
                     (s.sampler == SamplerKind::kCmj ? " (its pattern depends on the final spp)" : " (no error estimate)"));
  }
}

}  // namespace

uint64_t primitive_count(const Scene& scene) {
  uint64_t n = 0;
  for (const auto& o : scene.objects) {
    n += o.type == SceneObject::Type::kMesh && o.mesh >= 0 ? scene.meshes[size_t(o.mesh)].triangle_count() : 1;
  }
  return n;
}

namespace {

// The scene text as JSON; a syntax error names its line and column.
nlohmann::json parse_json(const std::string& text, const std::string& path) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    std::string what = e.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 5: ..." -> keep the reason.
    const auto colon = what.find(": ");
    throw SceneError(path + ":" + line_col(text, e.byte == 0 ? 0 : e.byte - 1) +
                     ": invalid JSON: " + (colon == std::string::npos ? what : what.substr(colon + 2)));
  } catch (const nlohmann::json::exception& e) {
    // nlohmann refuses numbers beyond double's range while parsing (e.g. 1e999).
    std::string what = e.what();
    const auto bracket = what.find("] ");
    throw SceneError(path + ": invalid JSON: " + (bracket == std::string::npos ? what : what.substr(bracket + 2)) +
                     " (numbers must be finite)");
  }
}

// "include": a glTF file's whole scene (camera, lights, materials, objects, animation) as the
// base that this file adds to (lights, materials, objects) or replaces (camera, image,
// background): hand edits on top of an export, without touching the export. Returns whether
// the file has one (*scene is then the glTF's).
bool read_include(const JsonReader& r, const fs::path& dir, const std::string& path, const SceneLoadOptions& options,
                  Scene* scene) {
  auto inc = r.find("include");
  if (!inc) return false;
  const std::string file = inc->string();
  if (!is_gltf_path(file)) inc->fail("must name a glTF file (.gltf or .glb)");
  const fs::path gltf_path = dir / file;
  if (!options.confine_to.empty()) {
    const fs::path rel = gltf_path.lexically_normal().lexically_relative(fs::path(options.confine_to).lexically_normal());
    if (rel.empty() || *rel.begin() == ".." || fs::path(file).is_absolute()) {
      inc->fail("'" + file + "' is outside the scene bundle (absolute, or climbs out with '..')");
    }
  }
  try {
    *scene = load_gltf_scene(gltf_path.string(), options);
  } catch (const SceneError& e) {
    inc->fail(e.what());
  }
  scene->path = path;
  const fs::path gltf_dir = fs::path(file).parent_path();
  for (auto& d : scene->dependencies) d = (gltf_dir / d).generic_string();
  scene->dependencies.push_back(file);
  return true;
}

void read_image(const JsonReader& img, const std::string& path, ImageSettings* settings) {
  ImageSettings& s = *settings;
  if (auto v = img.find("width")) s.width = int(v->integer_in(1, SceneLimits::kMaxResolution));
  if (auto v = img.find("height")) s.height = int(v->integer_in(1, SceneLimits::kMaxResolution));
  if (auto v = img.find("spp")) s.spp = int(v->integer_in(1, SceneLimits::kMaxSpp));
  if (auto v = img.find("max_depth")) s.max_depth = int(v->integer_in(0, SceneLimits::kMaxDepth));
  if (auto v = img.find("roulette_weight")) s.roulette_weight = v->number_in(0, 1);
  if (auto v = img.find("seed")) s.seed = uint64_t(v->integer_in(0, int64_t(1) << 53));
  if (auto v = img.find("sampler")) {
    s.sampler = *sampler_from_name(v->one_of({"sobol", "stratified", "cmj", "independent", "center", "lattice"}));
  }
  if (auto v = img.find("target_rmse")) {
    s.target_rmse = v->number_in(0, 1e30, true);
    if (img.find("spp")) v->fail("conflicts with image.spp: an adaptive render takes min_spp and max_spp instead");
  }
  if (auto v = img.find("block_rmse")) {
    s.block_rmse = v->number_in(0, 1e30, true);
    if (img.find("spp")) v->fail("conflicts with image.spp: an adaptive render takes min_spp and max_spp instead");
    if (img.find("target_rmse")) {
      v->fail("conflicts with image.target_rmse: a render is held to the frame's error or to every block's, not both");
    }
  }
  if (auto v = img.find("min_spp")) s.min_spp = int(v->integer_in(2, SceneLimits::kMaxSpp));
  if (auto v = img.find("max_spp")) s.max_spp = int(v->integer_in(2, SceneLimits::kMaxSpp));
  try {
    check_adaptive(s, [](const char* f) { return std::string("image.") + f; });
  } catch (const SceneError& e) {
    throw SceneError(path + ": " + e.what());
  }
  img.reject_unknown();
}

Light read_light(const JsonReader& l) {
  Light light;
  const std::string type = l.at("type").one_of({"point", "spot", "directional"});
  if (type == "point" || type == "spot") {
    light.type = type == "point" ? Light::Type::kPoint : Light::Type::kSpot;
    light.position = read_point(l.at("position"));
    light.intensity = l.at("intensity").rgb(kMaxRadiance);
  }
  if (type == "spot") {
    light.direction = read_direction(l.at("direction"));
    const double outer = l.at("outer_cone_deg").number_in(0.0, 90.0, true);
    double inner = 0;
    if (auto v = l.find("inner_cone_deg")) inner = v->number_in(0.0, outer);
    if (inner >= outer) l.at("inner_cone_deg").fail("must be less than outer_cone_deg");
    light.inner_cone_rad = inner * std::numbers::pi / 180;
    light.outer_cone_rad = outer * std::numbers::pi / 180;
  } else if (type == "directional") {
    light.type = Light::Type::kDirectional;
    light.direction = read_direction(l.at("direction"));
    light.irradiance = l.at("irradiance").rgb(kMaxRadiance);
  }
  l.reject_unknown();
  return light;
}

// The objects being read: names, the meshes loaded so far, and the primitives counted so far.
struct ObjectTable {
  std::map<std::string, int> material_index;  // name -> index into Scene::materials
  std::map<std::string, int> object_index;    // name -> index into Scene::objects
  std::map<std::string, int> mesh_cache;      // (file + exclusions) -> mesh index
  uint64_t primitives = 0;
};

// Loads mesh file obj->file (less `exclude`) once per (file, exclusions) and points obj->mesh at
// it; an explicit material makes it a copy with that material on every triangle.
void load_object_mesh(const JsonReader& o, const std::vector<std::string>& exclude, const fs::path& dir,
                      const std::string& path, const SceneLoadOptions& options, ObjectTable* table, SceneObject* obj,
                      Scene* scene) {
  std::string key = obj->file;
  for (const auto& e : exclude) key += "\n" + e;
  auto it = table->mesh_cache.find(key);
  if (it != table->mesh_cache.end()) {
    obj->mesh = it->second;
  } else {
    const fs::path mesh_path = dir / obj->file;
    if (!options.confine_to.empty()) {
      const fs::path rel = mesh_path.lexically_normal().lexically_relative(fs::path(options.confine_to).lexically_normal());
      if (rel.empty() || *rel.begin() == ".." || fs::path(obj->file).is_absolute()) {
        o.at("file").fail("'" + obj->file + "' is outside the scene bundle (absolute, or climbs out with '..')");
      }
    }
    MeshLoadResult loaded;
    try {
      // The remaining budget: a file over it is refused before it is flattened.
      const uint64_t budget =
          options.max_primitives == 0
              ? 0
              : std::max<uint64_t>(1, options.max_primitives - std::min(options.max_primitives, table->primitives));
      loaded = load_mesh(mesh_path.string(), exclude, options.confine_to, budget);
    } catch (const SceneError& e) {
      o.at("file").fail(e.what());
    }
    if (loaded.dropped_degenerate + loaded.dropped_nonfinite > 0) {
      spdlog::warn("{}: {}: dropped {} zero-area and {} non-finite triangles", path, obj->file,
                   loaded.dropped_degenerate, loaded.dropped_nonfinite);
    }
    // File materials join the scene's list; the mesh's ids are remapped to scene indices.
    const uint32_t offset = uint32_t(scene->materials.size());
    for (auto& m : loaded.materials) scene->materials.push_back(std::move(m));
    for (auto& id : loaded.mesh.material_ids) id += offset;
    obj->mesh = int(scene->meshes.size());
    scene->meshes.push_back(std::move(loaded.mesh));
    table->mesh_cache[key] = obj->mesh;
    scene->dependencies.push_back(obj->file);
    const fs::path mesh_dir = fs::path(obj->file).parent_path();
    for (const auto& lib : loaded.side_files) scene->dependencies.push_back((mesh_dir / lib).string());
  }
  if (options.max_primitives > 0 &&
      table->primitives + scene->meshes[size_t(obj->mesh)].triangle_count() > options.max_primitives) {
    o.fail("the scene has more than " + std::to_string(options.max_primitives) +
           " primitives (triangles of every mesh instance + spheres + planes): limit max_primitives");
  }
  if (obj->material >= 0) {
    // An explicit material overrides the file's for every triangle.
    Mesh copy = scene->meshes[size_t(obj->mesh)];
    std::fill(copy.material_ids.begin(), copy.material_ids.end(), uint32_t(obj->material));
    obj->mesh = int(scene->meshes.size());
    scene->meshes.push_back(std::move(copy));
  }
}

void read_objects(const std::vector<JsonReader>& objects, const fs::path& dir, const std::string& path,
                  const SceneLoadOptions& options, ObjectTable* table, Scene* scene) {
  for (const auto& o : objects) {
    std::vector<std::string> exclude;
    SceneObject obj = read_object(o, table->material_index, &exclude);
    if (obj.type != SceneObject::Type::kMesh && obj.material >= 0 &&
        scene->materials[size_t(obj.material)].is_emissive()) {
      o.at("material").fail("emissive materials are area lights and are supported on meshes only");
    }
    if (obj.type == SceneObject::Type::kMesh) load_object_mesh(o, exclude, dir, path, options, table, &obj, scene);
    table->primitives += obj.type == SceneObject::Type::kMesh ? scene->meshes[size_t(obj.mesh)].triangle_count() : 1;
    if (options.max_primitives > 0 && table->primitives > options.max_primitives) {
      o.fail("the scene has more than " + std::to_string(options.max_primitives) +
             " primitives (triangles of every mesh instance + spheres + planes): limit max_primitives");
    }
    if (!obj.name.empty()) {
      if (table->object_index.count(obj.name)) o.at("name").fail("duplicate object name '" + obj.name + "'");
      table->object_index[obj.name] = int(scene->objects.size());
    }
    scene->objects.push_back(std::move(obj));
  }
}

// Camera keyframes (they replace an included glTF's camera animation).
void read_camera_keys(const JsonReader& cams, int last, const CameraDesc& camera, Animation* a) {
  a->camera.clear();
  for (const auto& k : cams.array()) {
    CameraKey key;
    key.frame = int(k.at("frame").integer_in(0, last));
    key.camera = read_camera_fields(k, &camera);
    k.reject_unknown();
    if (!a->camera.empty() && key.frame <= a->camera.back().frame) {
      k.at("frame").fail("keyframes must be in strictly increasing frame order");
    }
    a->camera.push_back(key);
  }
}

// Keyframes of the named objects' transforms.
void read_object_keys(const JsonReader& objs, int last, const std::map<std::string, int>& object_index,
                      const std::vector<SceneObject>& objects, Animation* a) {
  for (const auto& [name, keys] : objs.members()) {
    auto it = object_index.find(name);
    if (it == object_index.end()) keys.fail("no object is named '" + name + "'");
    const SceneObject& obj = objects[size_t(it->second)];
    std::vector<TransformKey>& list = a->objects[it->second];
    for (const auto& k : keys.array()) {
      TransformKey key;
      key.frame = int(k.at("frame").integer_in(0, last));
      key.transform = read_transform(k, &obj.transform);
      k.reject_unknown();
      if (obj.type == SceneObject::Type::kSphere &&
          (key.transform.scale.x != key.transform.scale.y || key.transform.scale.y != key.transform.scale.z)) {
        k.fail("a sphere takes a uniform scale only");
      }
      if (!list.empty() && key.frame <= list.back().frame) {
        k.at("frame").fail("keyframes must be in strictly increasing frame order");
      }
      list.push_back(key);
    }
  }
}

void read_animation(const JsonReader& anim, const std::map<std::string, int>& object_index, Scene* scene) {
  Animation& a = scene->animation;
  a.frame_count = int(anim.at("frames").integer_in(1, SceneLimits::kMaxFrames));
  const int last = a.frame_count - 1;
  if (auto cams = anim.find("camera")) read_camera_keys(*cams, last, scene->camera, &a);
  if (auto objs = anim.find("objects")) read_object_keys(*objs, last, object_index, scene->objects, &a);
  anim.reject_unknown();
}

}  // namespace

Scene parse_scene(const std::string& text, const std::string& path, const SceneLoadOptions& options) {
  const nlohmann::json root = parse_json(text, path);
  const JsonReader r(root, path, "");
  if (!root.is_object()) r.fail("a scene file must be a JSON object");
  Scene scene;
  scene.path = path;

  const fs::path dir = fs::path(path).parent_path();
  const bool included = read_include(r, dir, path, options, &scene);

  if (auto camera = r.find("camera")) {
    scene.camera = read_camera_fields(*camera, nullptr);
    camera->reject_unknown();
    scene.animation.camera.clear();  // an included camera's animation goes with it
    scene.camera_aspect.reset();
  } else if (!included) {
    r.at("camera");
  }
  if (auto img = r.find("image")) read_image(*img, path, &scene.image);
  if (auto v = r.find("background")) scene.background = v->rgb(kMaxRadiance);
  if (auto lights = r.find("lights")) {
    for (const auto& l : lights->array()) scene.lights.push_back(read_light(l));
  }

  ObjectTable table;
  if (auto mats = r.find("materials")) {
    for (const auto& [name, m] : mats->members()) {
      table.material_index[name] = int(scene.materials.size());
      scene.materials.push_back(read_material(m, name));
    }
  }
  table.primitives = primitive_count(scene);  // an include's objects count too
  std::vector<JsonReader> objects;
  if (auto v = r.find("objects")) objects = v->array();
  else if (!included) r.at("objects");
  read_objects(objects, dir, path, options, &table, &scene);
  std::sort(scene.dependencies.begin(), scene.dependencies.end());
  scene.dependencies.erase(std::unique(scene.dependencies.begin(), scene.dependencies.end()),
                           scene.dependencies.end());

  if (auto anim = r.find("animation")) read_animation(*anim, table.object_index, &scene);
  r.reject_unknown();
  return scene;
}

Scene load_scene(const std::string& path, const SceneLoadOptions& options) {
  if (is_gltf_path(path)) return load_gltf_scene(path, options);  // a glTF file is a whole scene
  // Refused rather than ignored, also on the farm: a job must render what its flags say.
  if (options.gltf.given()) throw SceneError(path + ": --camera, --scene-index and --fps apply to glTF scenes (.gltf, .glb) only");
  std::error_code ec;
  if (!fs::exists(path, ec)) throw SceneError(path + ": scene file not found");
  if (!fs::is_regular_file(path, ec)) throw SceneError(path + ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path + ": cannot open scene file for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_scene(ss.str(), path, options);
}

void apply_overrides(Scene& scene, const ImageOverrides& o) {
  auto check = [&](const char* field, int64_t v, int64_t lo, int64_t hi) {
    if (v < lo || v > hi) {
      throw SceneError(std::string("--") + field + ": must be in [" + std::to_string(lo) + ", " +
                       std::to_string(hi) + "], got " + std::to_string(v));
    }
  };
  if (o.width) { check("width", *o.width, 1, SceneLimits::kMaxResolution); scene.image.width = *o.width; }
  if (o.height) { check("height", *o.height, 1, SceneLimits::kMaxResolution); scene.image.height = *o.height; }
  if (scene.camera_aspect && (o.width.has_value() != o.height.has_value())) {
    // A glTF camera's aspect ratio fills in the side not given.
    const double a = *scene.camera_aspect;
    if (o.width) scene.image.height = std::clamp(int(std::lround(*o.width / a)), 1, SceneLimits::kMaxResolution);
    else scene.image.width = std::clamp(int(std::lround(*o.height * a)), 1, SceneLimits::kMaxResolution);
  }
  if (o.spp) { check("spp", *o.spp, 1, SceneLimits::kMaxSpp); scene.image.spp = *o.spp; }
  if (o.max_depth) { check("max-depth", *o.max_depth, 0, SceneLimits::kMaxDepth); scene.image.max_depth = *o.max_depth; }
  if (o.seed) scene.image.seed = *o.seed;
  if (o.roulette_weight) {
    // NaN fails both comparisons.
    if (!(*o.roulette_weight >= 0 && *o.roulette_weight <= 1)) {
      throw SceneError("--roulette-weight: must be in [0, 1] (a path weight; 0 traces every branch), got " +
                       std::to_string(*o.roulette_weight));
    }
    scene.image.roulette_weight = *o.roulette_weight;
  }
  if (o.sampler) scene.image.sampler = *o.sampler;
  if (o.target_rmse && o.block_rmse) {
    throw SceneError("--target-rmse and --block-rmse conflict: a render is held to the frame's error or to every "
                     "block's, not both");
  }
  for (const auto& [value, flag] : {std::pair{o.target_rmse, "--target-rmse"}, std::pair{o.block_rmse, "--block-rmse"}}) {
    if (!value) continue;
    if (!std::isfinite(*value) || !(*value > 0)) {
      throw SceneError(std::string(flag) + ": must be a finite number > 0 (RMSE in linear light), got " +
                       std::to_string(*value));
    }
    if (o.spp) {
      throw SceneError(std::string("--spp and ") + flag + " conflict: a render to a target error takes --min-spp and "
                       "--max-spp as its bounds instead of --spp");
    }
  }
  if (o.target_rmse) {
    scene.image.target_rmse = *o.target_rmse;
    scene.image.block_rmse = 0;  // the command line's target replaces the scene file's
  } else if (o.block_rmse) {
    scene.image.block_rmse = *o.block_rmse;
    scene.image.target_rmse = 0;
  } else if (o.spp) {
    scene.image.target_rmse = scene.image.block_rmse = 0;  // an explicit spp asks for a uniform render
  }
  if (o.min_spp) { check("min-spp", *o.min_spp, 2, SceneLimits::kMaxSpp); scene.image.min_spp = *o.min_spp; }
  if (o.max_spp) { check("max-spp", *o.max_spp, 2, SceneLimits::kMaxSpp); scene.image.max_spp = *o.max_spp; }
  if ((o.min_spp || o.max_spp) && !scene.image.adaptive()) {
    throw SceneError(std::string(o.min_spp ? "--min-spp" : "--max-spp") +
                     " bounds a render to a target error: give --target-rmse or --block-rmse too (or --spp for a "
                     "uniform render)");
  }
  check_adaptive(scene.image, [](const char* f) {
    std::string flag = std::string("--") + f;
    for (char& c : flag) c = c == '_' ? '-' : c;
    return flag;
  });
}

}  // namespace tessera

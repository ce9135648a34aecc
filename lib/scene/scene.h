// SPDX-License-Identifier: Apache-2.0
// The scene description: what a scene file says, in world space and double precision.
// A Scene is plain data (no Embree, no gRPC); frame F of it is fully defined by the file and F
// (see animation.h). The renderer converts one frame to camera-relative float geometry.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "math/vec3.h"

namespace tessera {

// The camera as written in the file: either look-at form or the classic screen-plane form.
struct CameraDesc {
  enum class Form { kLookAt, kScreenPlane };
  Form form = Form::kLookAt;
  // kLookAt
  Vec3d position{0, 0, 0};
  Vec3d look_at{0, 0, -1};
  Vec3d up{0, 1, 0};
  double vfov_deg = 45.0;
  // kScreenPlane: pixel point p(u,v) = p0 + u(p1-p0) + v(p2-p0), u right, v down, in [0,1].
  Vec3d eye{0, 0, 0};
  Vec3d p0{-1, 1, -1}, p1{1, 1, -1}, p2{-1, -1, -1};
};

// The screen plane every camera reduces to for a given aspect ratio.
struct ScreenPlane {
  Vec3d eye, p0, p1, p2;
};
ScreenPlane screen_plane(const CameraDesc& camera, int width, int height);

enum class SamplerKind {
  kSobol,        // Owen-scrambled Sobol (0,2)-sequence, progressive: every 2^k prefix is stratified; the default
  kCmj,          // correlated multi-jittered (Kensler 2013): stratified for a fixed spp only (comparison)
  kIndependent,  // independent uniform random samples (comparison)
  kCenter,       // every sample at the pixel center: no anti-aliasing (analytic tests)
  // Frame targets only: a lattice of pixel corners shared by neighbouring pixels, the mean of the
  // corners where they are smooth, audited by hold-out samples, and kSobol's two streams elsewhere
  // (render/lattice_sampler.h)
  kLattice,
};

struct ImageSettings {
  int width = 640;
  int height = 480;
  int spp = 16;       // samples per pixel of a uniform render (target_rmse == 0)
  int max_depth = 8;  // secondary bounces (reflection/refraction) after the camera ray's hit
  // Russian roulette on reflection and refraction rays whose path weight (the largest channel of
  // the reflectances, Fresnel factors and transmittances from the camera) is below this; 0
  // traces every branch of the tree down to max_depth (render/integrator.cpp).
  double roulette_weight = 0.01;
  uint64_t seed = 0;
  SamplerKind sampler = SamplerKind::kSobol;
  // Rendering to a target error (docs/renderer.md, "Rendering to a target error"), between
  // min_spp and max_spp samples per pixel; spp is then unused. At most one of the two is > 0:
  //  - target_rmse: the frame's estimated RMSE (linear light) is at most this; samples go where
  //    they lower it most per unit of cost (render/frame_target.h);
  //  - block_rmse: every block of 8x8 pixels takes samples until its own estimated RMSE is at
  //    most this (render/adaptive.h).
  double target_rmse = 0;
  double block_rmse = 0;
  int min_spp = 0;  // 0: the mode's default, first_spp()
  int max_spp = 1024;
  bool adaptive() const { return target_rmse > 0 || block_rmse > 0; }
  bool frame_target() const { return target_rmse > 0; }
  // The target this render is held to: the frame's RMSE or every block's.
  double target() const { return target_rmse > 0 ? target_rmse : block_rmse; }
  // The fewest samples a pixel takes in an adaptive render: min_spp, by default 2 for a frame
  // target (its pilot pass: the least that gives each pixel two streams and an estimate; edges
  // its samples miss are found by the planner's contrast floor, sampling/pass_plan.cpp, and 2
  // reaches the Whitted showcase's loose targets with 1.4x fewer rays than 4, its estimate as
  // honest; docs/performance.md, "Target-error renders against uniform spp") and 16 for the
  // block bound (a block deciding alone needs 16 to see small features).
  int first_spp() const { return min_spp > 0 ? min_spp : frame_target() ? 2 : 16; }
};

struct Material {
  enum class Type { kDiffuse, kMirror, kGlass };
  std::string name;
  Type type = Type::kDiffuse;
  Rgb albedo{0.8f, 0.8f, 0.8f};  // diffuse
  bool checker = false;           // diffuse: procedural checker between albedo and albedo2
  Rgb albedo2{0.2f, 0.2f, 0.2f};
  double checker_scale = 1.0;     // world-space size of one checker square
  Rgb reflectance{1, 1, 1};       // mirror
  double ior = 1.5;               // glass
  Rgb transmittance{1, 1, 1};     // glass: multiplies each refraction and each shadow-ray crossing
  Rgb emission{0, 0, 0};          // radiance emitted (OBJ Ke); emissive meshes are area lights
  // diffuse (glTF): albedo x texture (Scene::textures index, -1 none) at the mesh's uv, after
  // uv' = uv_transform * (u, v, 1), a row-major 2x3 (KHR_texture_transform).
  int albedo_texture = -1;
  int uv_set = 0;  // TEXCOORD_n the texture reads (the loader's concern)
  std::array<double, 6> uv_transform{1, 0, 0, 0, 1, 0};

  bool is_emissive() const { return emission.x > 0 || emission.y > 0 || emission.z > 0; }
};

struct Light {
  enum class Type { kPoint, kDirectional, kSpot };
  Type type = Type::kPoint;
  Vec3d position{0, 0, 0};   // point, spot
  Rgb intensity{1, 1, 1};    // point, spot: irradiance at distance r is I cos(theta) / r^2 (on the spot's axis)
  Vec3d direction{0, -1, 0}; // directional, spot: the direction the light travels (unit)
  Rgb irradiance{1, 1, 1};   // directional: irradiance E cos(theta)
  // spot (glTF KHR_lights_punctual): full intensity within inner_cone_rad of the axis, none
  // beyond outer_cone_rad, and between them the extension's smooth falloff (SpotLight::falloff in
  // render/render_scene.h).
  double inner_cone_rad = 0;
  double outer_cone_rad = 0.7853981633974483;
};

// translate * rotate(X then Y then Z, degrees) * scale, applied to object space.
// A glTF node's world transform is a general affine matrix (a parent's non-uniform scale shears
// a rotated child), which no translate/rotate/scale triple can hold: `matrix` (row-major 3x4,
// p' = M p + t) then replaces the three.
struct TransformDesc {
  Vec3d translate{0, 0, 0};
  Vec3d rotate_deg{0, 0, 0};
  Vec3d scale{1, 1, 1};
  std::optional<std::array<double, 12>> matrix;
};

// Triangle mesh in object space, as loaded from a file.
struct Mesh {
  std::vector<Vec3f> positions;
  std::vector<uint32_t> indices;        // 3 per triangle
  std::vector<uint32_t> material_ids;   // one per triangle, index into Scene::materials
  std::vector<float> uvs;               // texture coordinates, 2 per vertex; empty: none
  // Vertex normals (glTF NORMAL), 1 per vertex, for interpolated shading; empty: flat shading.
  // A zero normal marks a vertex without one (its triangles shade flat).
  std::vector<Vec3f> normals;
  size_t triangle_count() const { return indices.size() / 3; }
};

// An image texture, decoded to linear light (glTF base color textures are sRGB-encoded).
// Texel (x, y) covers uv in [x/W, (x+1)/W) x [y/H, (y+1)/H): v runs down the image, as in glTF.
struct Texture {
  std::string name;
  int width = 0, height = 0;
  // Row-major, top row first; shared, so each frame's RenderScene copies a pointer, not the image.
  std::shared_ptr<const std::vector<Rgb>> texels;
  bool nearest = false;     // magnification filter NEAREST; else bilinear
  enum class Wrap { kRepeat, kClamp, kMirror };
  Wrap wrap_s = Wrap::kRepeat, wrap_t = Wrap::kRepeat;
};

struct SceneObject {
  enum class Type { kSphere, kPlane, kMesh };
  Type type = Type::kSphere;
  std::string name;
  int material = -1;             // index into Scene::materials; for meshes -1 = the file's materials
  TransformDesc transform;       // sphere: uniform scale only
  // sphere (object space)
  Vec3d center{0, 0, 0};
  double radius = 1.0;
  // plane (object space)
  Vec3d point{0, 0, 0};
  Vec3d normal{0, 1, 0};
  // mesh
  std::string file;              // as written in the scene file (relative to it)
  int mesh = -1;                 // index into Scene::meshes
};

// Keyframes are interpolated linearly; before the first and after the last they hold.
struct CameraKey {
  int frame = 0;
  CameraDesc camera;
};
struct TransformKey {
  int frame = 0;
  TransformDesc transform;
};

struct Animation {
  int frame_count = 1;
  std::vector<CameraKey> camera;                        // sorted by frame
  std::map<int, std::vector<TransformKey>> objects;     // object index -> keys sorted by frame
};

struct Scene {
  std::string path;             // the scene file it was loaded from
  CameraDesc camera;
  ImageSettings image;
  Rgb background{0, 0, 0};
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<SceneObject> objects;
  std::vector<Mesh> meshes;
  std::vector<Texture> textures;
  Animation animation;
  // A glTF camera's aspectRatio: the image's width/height when neither is given, and the other
  // side when one is (apply_overrides); the vertical field of view is kept exactly either way.
  std::optional<double> camera_aspect;
  // Every file the scene reads besides itself (meshes and their material libraries), as paths
  // relative to the scene file's directory: a scene bundle is the scene file plus these.
  std::vector<std::string> dependencies;

  int frame_count() const { return animation.frame_count; }
};

}  // namespace tessera

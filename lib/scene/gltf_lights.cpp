// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_lights.h"

#include <spdlog/spdlog.h>

#include <numbers>

namespace tessera {

namespace {

// The light's color x intensity in radiometric units; `gp` is its glTF path.
Rgb radiometric_power(const GltfReader& r, const tinygltf::Light& gl, const std::string& gp) {
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
  return color * float(gl.intensity / 683.0);
}

// The light of node n, at its world transform m, of the given power.
Light place_light(const GltfReader& r, const tinygltf::Light& gl, const std::string& gp, const Matrix4& m, size_t n,
                  const Rgb& radiometric) {
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
  return L;
}

}  // namespace

void read_gltf_lights(const GltfReader& r, const GltfNodeTree& tree, const GltfAnimation& animation,
                      const std::string& path, std::vector<Light>* lights) {
  const tinygltf::Model& model = r.g_;
  for (const NodeInstance& inst : tree.instances) {
    const size_t n = size_t(inst.chain.back());
    auto it = model.nodes[n].extensions.find("KHR_lights_punctual");
    if (it == model.nodes[n].extensions.end()) continue;
    const std::string lp = idx("nodes", n) + ".extensions.KHR_lights_punctual.light";
    if (!it->second.IsObject() || !it->second.Has("light") || !it->second.Get("light").IsInt()) r.fail(lp, "must be a light index");
    const int li = it->second.Get("light").GetNumberAsInt();
    if (li < 0 || size_t(li) >= model.lights.size()) r.fail(lp, "light " + std::to_string(li) + " does not exist");
    const auto& gl = model.lights[size_t(li)];
    const std::string gp = "extensions.KHR_lights_punctual." + idx("lights", size_t(li));
    if (animation.is_animated(inst)) spdlog::warn("{}: {}: animated lights keep their frame-0 pose", path, gp);
    const Rgb radiometric = radiometric_power(r, gl, gp);
    const Light L = place_light(r, gl, gp, animation.world_at(inst, 0), n, radiometric);
    if (gl.range > 0) spdlog::warn("{}: {}: range {} ignored (light falls off as 1/r^2 without a cutoff)", path, gp, gl.range);
    lights->push_back(L);
  }
}

}  // namespace tessera

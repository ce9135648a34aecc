// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_animation.h"

#include <algorithm>
#include <cmath>

#include "scene/scene_limits.h"

namespace tessera {

namespace {

// Channel ci of animations[ai], checked; false for a morph target weights channel (not
// supported: the geometry stays unchanged).
bool read_channel(const GltfReader& r, size_t ai, size_t ci, GltfChannel* channel) {
  const tinygltf::Model& model = r.g_;
  const auto& anim = model.animations[ai];
  const auto& ch = anim.channels[ci];
  const std::string cp = idx("animations", ai) + "." + idx("channels", ci);
  if (ch.target_path == "weights") return false;  // morph targets: not supported, geometry unchanged
  if (ch.target_path != "translation" && ch.target_path != "rotation" && ch.target_path != "scale") {
    r.fail(cp + ".target.path", "must be translation, rotation, scale or weights");
  }
  if (ch.target_node < 0 || size_t(ch.target_node) >= model.nodes.size()) r.fail(cp + ".target.node", "does not exist");
  if (ch.sampler < 0 || size_t(ch.sampler) >= anim.samplers.size()) r.fail(cp + ".sampler", "does not exist");
  const auto& smp = anim.samplers[size_t(ch.sampler)];
  const std::string sp = idx("animations", ai) + "." + idx("samplers", size_t(ch.sampler));
  GltfChannel c{ch.target_node, ch.target_path, {}, {}, ch.target_path == "rotation" ? 4 : 3, smp.interpolation};
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
  *channel = std::move(c);
  return true;
}

// The channel's value at time t: held before the first key and after the last.
void sample(const GltfChannel& c, double t, double out[4]) {
  const size_t nk = c.times.size();
  const bool cubic = c.interp == "CUBICSPLINE";
  auto value = [&](size_t key, int j) { return c.values[(cubic ? 3 * key + 1 : key) * size_t(c.n) + size_t(j)]; };
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
}

}  // namespace

GltfAnimation::GltfAnimation(const GltfReader& r, const GltfNodeTree& tree, const std::string& path,
                             const GltfOptions& options)
    : tree_(tree) {
  const tinygltf::Model& model = r.g_;
  double duration = 0;
  for (size_t ai = 0; ai < model.animations.size(); ++ai) {
    for (size_t ci = 0; ci < model.animations[ai].channels.size(); ++ci) {
      GltfChannel c;
      if (!read_channel(r, ai, ci, &c)) continue;
      duration = std::max(duration, c.times.back());
      channels_.push_back(std::move(c));
    }
  }
  const double fps = options.fps;
  if (!(fps > 0 && fps <= GltfOptions::kMaxFps)) {
    throw SceneError(path + ": --fps: must be in (0, " + std::to_string(int(GltfOptions::kMaxFps)) + "], got " + std::to_string(fps));
  }
  // Key times are float32 (glTF accessors): an exporter's key at frame 20 of 24 fps is stored as
  // float32(20/24), and 24 times that is 19.9999995, whose floor would drop the key's own frame.
  // A relative allowance of 2^-20 covers float32's rounding of the time (2^-24 of it) with room
  // to spare; at most it counts a key a tenth of a frame short of a frame as reaching it, at
  // kMaxFrames, which only adds a frame holding the last pose.
  const double frames_d = std::floor(duration * fps * (1 + 0x1p-20)) + 1;
  if (frames_d > SceneLimits::kMaxFrames) {
    throw SceneError(path + ": the animation lasts " + std::to_string(duration) + " s: more than " +
                     std::to_string(SceneLimits::kMaxFrames) + " frames at --fps " + std::to_string(fps));
  }
  frame_count_ = channels_.empty() ? 1 : int(frames_d);
  fps_ = fps;
  node_animated_.assign(model.nodes.size(), false);
  for (const GltfChannel& c : channels_) {
    node_animated_[size_t(c.node)] = true;
    if (tree.rest_matrix[size_t(c.node)]) r.fail(idx("nodes", size_t(c.node)), "is animated but has a matrix (glTF requires TRS)");
  }
}

Matrix4 GltfAnimation::local_at(int n, double t, bool animated) const {
  const std::vector<Trs>& rest = tree_.rest;
  if (!animated) return tree_.rest_matrix[size_t(n)] ? *tree_.rest_matrix[size_t(n)] : trs_matrix(rest[size_t(n)]);
  Trs v = rest[size_t(n)];
  for (const GltfChannel& c : channels_) {
    if (c.node != n) continue;
    double out[4];
    sample(c, t, out);
    if (c.target == "translation") v.t = {out[0], out[1], out[2]};
    else if (c.target == "scale") v.s = {out[0], out[1], out[2]};
    else v.q = {out[0], out[1], out[2], out[3]};
  }
  return trs_matrix(v);
}

Matrix4 GltfAnimation::world_at(const NodeInstance& inst, double t) const {
  Matrix4 m;
  for (int n : inst.chain) m = m * local_at(n, t, node_animated_[size_t(n)]);
  return m;
}

bool GltfAnimation::is_animated(const NodeInstance& inst) const {
  return std::any_of(inst.chain.begin(), inst.chain.end(), [&](int n) { return node_animated_[size_t(n)]; });
}

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
#include "scene/animation.h"

#include <cmath>
#include <numbers>

namespace tessera {

namespace {

// Finds the keys around `frame` and the blend weight; works for any key type with `.frame`.
template <typename Key>
std::pair<const Key*, const Key*> bracket(const std::vector<Key>& keys, int frame, double* w) {
  *w = 0.0;
  if (frame <= keys.front().frame) return {&keys.front(), &keys.front()};
  if (frame >= keys.back().frame) return {&keys.back(), &keys.back()};
  for (size_t i = 1; i < keys.size(); ++i) {
    if (frame <= keys[i].frame) {
      *w = double(frame - keys[i - 1].frame) / double(keys[i].frame - keys[i - 1].frame);
      return {&keys[i - 1], &keys[i]};
    }
  }
  return {&keys.back(), &keys.back()};
}

CameraDesc lerp_camera(const CameraDesc& a, const CameraDesc& b, double w) {
  CameraDesc c = a;
  c.position = lerp(a.position, b.position, w);
  c.look_at = lerp(a.look_at, b.look_at, w);
  c.up = lerp(a.up, b.up, w);
  c.vfov_deg = a.vfov_deg * (1 - w) + b.vfov_deg * w;
  c.eye = lerp(a.eye, b.eye, w);
  c.p0 = lerp(a.p0, b.p0, w);
  c.p1 = lerp(a.p1, b.p1, w);
  c.p2 = lerp(a.p2, b.p2, w);
  return c;
}

TransformDesc lerp_transform(const TransformDesc& a, const TransformDesc& b, double w) {
  if (a.matrix || b.matrix) {
    // Matrix keys come from glTF animations, one per frame (gltf_scene.cpp): a frame is always
    // exactly at a key, and the element-wise blend is only ever taken at w = 0 or 1.
    if (w == 0.0 || !b.matrix) return a;
    if (w == 1.0 || !a.matrix) return b;
    TransformDesc t = a;
    for (size_t i = 0; i < 12; ++i) (*t.matrix)[i] = (*a.matrix)[i] * (1 - w) + (*b.matrix)[i] * w;
    return t;
  }
  return {lerp(a.translate, b.translate, w), lerp(a.rotate_deg, b.rotate_deg, w), lerp(a.scale, b.scale, w), {}};
}

}  // namespace

ScreenPlane screen_plane(const CameraDesc& c, int width, int height) {
  if (c.form == CameraDesc::Form::kScreenPlane) return {c.eye, c.p0, c.p1, c.p2};
  // Look-at: a screen plane at distance 1 in front of the eye, square pixels.
  const Vec3d forward = normalize(c.look_at - c.position);
  const Vec3d right = normalize(cross(forward, c.up));
  const Vec3d up = cross(right, forward);
  const double half_h = std::tan(c.vfov_deg * std::numbers::pi / 360.0);
  const double half_w = half_h * double(width) / double(height);
  const Vec3d center = c.position + forward;
  ScreenPlane s;
  s.eye = c.position;
  s.p0 = center - right * half_w + up * half_h;
  s.p1 = center + right * half_w + up * half_h;
  s.p2 = center - right * half_w - up * half_h;
  return s;
}

FrameState evaluate_frame(const Scene& scene, int frame) {
  FrameState s;
  s.frame = frame;
  s.camera = scene.camera;
  double w = 0;
  if (!scene.animation.camera.empty()) {
    auto [a, b] = bracket(scene.animation.camera, frame, &w);
    s.camera = lerp_camera(a->camera, b->camera, w);
  }
  s.transforms.reserve(scene.objects.size());
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    auto it = scene.animation.objects.find(int(i));
    if (it == scene.animation.objects.end() || it->second.empty()) {
      s.transforms.push_back(scene.objects[i].transform);
    } else {
      auto [a, b] = bracket(it->second, frame, &w);
      s.transforms.push_back(lerp_transform(a->transform, b->transform, w));
    }
  }
  return s;
}

}  // namespace tessera

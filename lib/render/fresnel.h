// SPDX-License-Identifier: Apache-2.0
// Reflection, refraction and the exact unpolarized Fresnel reflectance of a dielectric.
#pragma once

#include <cmath>

#include "math/vec3.h"

namespace tessera {

inline Vec3f reflect(const Vec3f& d, const Vec3f& n) { return d - n * (2.0f * dot(d, n)); }

// Fresnel reflectance for light going from index eta_i into eta_t, cos_i = cos of the
// incidence angle (>= 0). Returns 1 for total internal reflection. Average of the s and p
// polarizations (Born & Wolf; pbrt-v4 FrDielectric).
inline float fresnel_dielectric(float cos_i, float eta_i, float eta_t, float* cos_t_out) {
  cos_i = std::fmin(std::fmax(cos_i, 0.0f), 1.0f);
  if (eta_i == eta_t) {  // index-matched: no interface at all, exactly
    *cos_t_out = cos_i;
    return 0.0f;
  }
  const float eta = eta_i / eta_t;
  const float sin2_t = eta * eta * std::fmax(0.0f, 1.0f - cos_i * cos_i);
  if (sin2_t >= 1.0f) {
    *cos_t_out = 0.0f;
    return 1.0f;
  }
  const float cos_t = std::sqrt(1.0f - sin2_t);
  *cos_t_out = cos_t;
  const float rs = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
  const float rp = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
  return 0.5f * (rs * rs + rp * rp);
}

// Refracted direction for unit d hitting a surface with unit normal n facing against d
// (dot(d, n) <= 0), relative index eta = eta_i / eta_t, given cos_t from fresnel_dielectric.
inline Vec3f refract(const Vec3f& d, const Vec3f& n, float eta, float cos_i, float cos_t) {
  return normalize(d * eta + n * (eta * cos_i - cos_t));
}

}  // namespace tessera

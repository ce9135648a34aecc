// SPDX-License-Identifier: Apache-2.0
#include "rays/ray_check.h"

#include <cmath>

namespace tessera::rays {

std::string check_ray(const WorldRay& r, size_t index, std::string* field) {
  auto problem = [&](const char* name, const std::string& what) {
    if (field) *field = name;
    return "ray " + std::to_string(index) + ": " + name + " " + what;
  };
  if (!is_finite(r.o)) return problem("origin", "is not finite");
  // The renderer traces in float: beyond this an origin (minus the eye) would round to infinity.
  if (max_component(abs(r.o)) > kMaxOrigin) return problem("origin", "is beyond 1e30 (float range)");
  if (!is_finite(r.d)) return problem("direction", "is not finite");
  // Any nonzero component will do: the tracer scales before normalizing (no underflow).
  if (!(max_component(abs(r.d)) > 0.0)) return problem("direction", "is zero-length");
  if (std::isnan(r.tmin) || r.tmin < 0.0f || std::isinf(r.tmin)) {
    return problem("t_min", "must be finite and >= 0 (got " + std::to_string(r.tmin) + ")");
  }
  if (std::isnan(r.tmax)) return problem("t_max", "is NaN");
  if (r.tmin > r.tmax) {
    return problem("t_min", "> t_max (" + std::to_string(r.tmin) + " > " + std::to_string(r.tmax) + ")");
  }
  return "";
}

}  // namespace tessera::rays

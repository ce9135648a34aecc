// SPDX-License-Identifier: Apache-2.0
// Which of a hit's fields a client wants: the response field mask of tessera.v1.TraceRequest
// (`fields`, docs/rays.md) and `tessera rays --fields`. Many clients need a fraction of the
// answer (a lidar only t, a visibility test only hit), and over the network every field not
// sent is bytes, copies and parsing saved. `hit` (and the ids) are always part of an answer, so
// they are not fields here.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "rays/rays_error.h"

namespace tessera::rays {

// In the order of the answer's columns; the proto's HitField is this + 1 (0 is UNSPECIFIED).
enum class HitField : uint8_t { kT, kPoint, kNormal, kShadingNormal, kBarycentrics, kObject, kPrimitive, kMaterial };
inline constexpr int kHitFieldCount = 8;

class HitFields {
 public:
  constexpr HitFields() = default;  // none: hit alone
  static constexpr HitFields all() { return HitFields(uint8_t((1u << kHitFieldCount) - 1)); }

  constexpr HitFields with(HitField f) const { return HitFields(uint8_t(bits_ | 1u << unsigned(f))); }
  constexpr bool has(HitField f) const { return (bits_ >> unsigned(f)) & 1u; }
  constexpr bool is_all() const { return *this == all(); }
  // The fields asked for, in column order.
  std::vector<HitField> list() const;
  constexpr bool operator==(const HitFields&) const = default;

 private:
  constexpr explicit HitFields(uint8_t bits) : bits_(bits) {}
  uint8_t bits_ = 0;
};

// The CLI's name of a field: "t", "point", "normal", "shading_normal", "barycentrics", "object",
// "primitive", "material".
std::string_view hit_field_name(HitField f);
// The fields' names as a comma list, in column order ("t,object"): parse_hit_fields()'s input.
std::string hit_field_names(HitFields fields);
// The output columns a field fills, as `tessera rays` names them: point is px,py,pz, and so on.
const std::vector<std::string_view>& hit_field_columns(HitField f);
// A comma list of field names ("t,object"; repeats and any order are fine). Throws
// RaysError naming the first bad name (or an empty list) and the allowed names.
HitFields parse_hit_fields(std::string_view list);

}  // namespace tessera::rays

// SPDX-License-Identifier: Apache-2.0
#include "rays/hit_fields.h"

#include <array>

#include "rays/rays_error.h"

namespace tessera::rays {

namespace {

struct FieldInfo {
  std::string_view name;
  std::vector<std::string_view> columns;
};

const std::array<FieldInfo, kHitFieldCount>& infos() {
  static const std::array<FieldInfo, kHitFieldCount> table{{
      {"t", {"t"}},
      {"point", {"px", "py", "pz"}},
      {"normal", {"nx", "ny", "nz"}},
      {"shading_normal", {"snx", "sny", "snz"}},
      {"barycentrics", {"u", "v"}},
      {"object", {"object"}},
      {"primitive", {"primitive"}},
      {"material", {"material"}},
  }};
  return table;
}

}  // namespace

std::vector<HitField> HitFields::list() const {
  std::vector<HitField> out;
  for (int k = 0; k < kHitFieldCount; ++k) {
    if (has(HitField(k))) out.push_back(HitField(k));
  }
  return out;
}

std::string_view hit_field_name(HitField f) { return infos()[size_t(f)].name; }

std::string hit_field_names(HitFields fields) {
  std::string s;
  for (HitField f : fields.list()) s += (s.empty() ? "" : ",") + std::string(hit_field_name(f));
  return s;
}

const std::vector<std::string_view>& hit_field_columns(HitField f) { return infos()[size_t(f)].columns; }

HitFields parse_hit_fields(std::string_view list) {
  HitFields fields;
  size_t begin = 0;
  while (true) {
    const size_t end = std::min(list.find(',', begin), list.size());
    const std::string_view name = list.substr(begin, end - begin);
    size_t k = 0;
    while (k < infos().size() && infos()[k].name != name) ++k;
    if (k == infos().size()) {
      throw RaysError((name.empty() ? std::string("an empty name") : "'" + std::string(name) + "'") +
                      " is not a hit field (allowed: " + hit_field_names(HitFields::all()) + ")");
    }
    fields = fields.with(HitField(k));
    if (end == list.size()) return fields;
    begin = end + 1;
  }
}

}  // namespace tessera::rays

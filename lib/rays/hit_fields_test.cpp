// SPDX-License-Identifier: Apache-2.0
// The field mask's names: what `tessera rays --fields` accepts and how it refuses the rest.
#include "rays/hit_fields.h"

#include <gtest/gtest.h>

namespace tessera::rays {
namespace {

std::string error_of(std::string_view list) {
  try {
    parse_hit_fields(list);
  } catch (const RaysError& e) {
    return e.what();
  }
  return "no error";
}

TEST(HitFields, ParsesNamesInAnyOrderWithRepeats) {
  const HitFields f = parse_hit_fields("object,t,object");
  EXPECT_EQ(f, HitFields().with(HitField::kT).with(HitField::kObject));
  EXPECT_EQ(f.list(), (std::vector<HitField>{HitField::kT, HitField::kObject}));  // column order
  EXPECT_FALSE(f.has(HitField::kPoint));
  EXPECT_TRUE(parse_hit_fields("t,point,normal,shading_normal,barycentrics,object,primitive,material").is_all());
  EXPECT_EQ(HitFields::all().list().size(), size_t(kHitFieldCount));
  EXPECT_TRUE(HitFields().list().empty());
  for (int k = 0; k < kHitFieldCount; ++k) {
    EXPECT_EQ(parse_hit_fields(hit_field_name(HitField(k))).list(), std::vector<HitField>{HitField(k)});
  }
  EXPECT_EQ(hit_field_columns(HitField::kPoint), (std::vector<std::string_view>{"px", "py", "pz"}));
  EXPECT_EQ(hit_field_columns(HitField::kBarycentrics), (std::vector<std::string_view>{"u", "v"}));
}

TEST(HitFields, RefusesUnknownNamesListingTheAllowedOnes) {
  const std::string allowed = "(allowed: t,point,normal,shading_normal,barycentrics,object,primitive,material)";
  EXPECT_EQ(error_of("t,pointz"), "'pointz' is not a hit field " + allowed);
  EXPECT_EQ(error_of("px"), "'px' is not a hit field " + allowed);  // a column, not a field
  EXPECT_EQ(error_of("T"), "'T' is not a hit field " + allowed);
  EXPECT_EQ(error_of(""), "an empty name is not a hit field " + allowed);
  EXPECT_EQ(error_of("t,,object"), "an empty name is not a hit field " + allowed);
  EXPECT_EQ(error_of("t,"), "an empty name is not a hit field " + allowed);
}

}  // namespace
}  // namespace tessera::rays

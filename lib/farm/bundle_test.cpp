// SPDX-License-Identifier: Apache-2.0
// Bundle validation: what a hostile client could upload is refused before anything is written.
#include "farm/bundle.h"

#include <gtest/gtest.h>

#include "tessera/v1/common.pb.h"

namespace tessera::farm {
namespace {

std::string bundle(const std::string& scene, const std::vector<std::string>& paths) {
  tessera::v1::Bundle b;
  b.set_scene_file(scene);
  for (const auto& p : paths) {
    auto* f = b.add_files();
    f->set_path(p);
    f->set_content("{}");
  }
  return b.SerializeAsString();
}

std::string refusal(const std::string& bytes) {
  tessera::v1::Bundle out;
  try {
    parse_bundle(bytes, &out);
  } catch (const BundleError& e) {
    return e.what();
  }
  return {};
}

TEST(Bundle, SafePathsAreRelativeAndStayInside) {
  EXPECT_TRUE(is_safe_bundle_path("scene.json"));
  EXPECT_TRUE(is_safe_bundle_path("models/a b/mesh.obj"));
  for (const char* bad : {"", "/etc/passwd", "../x", "a/../../x", "a/./b", "a//b", "a/", "a\\b", ".tessera-scene"}) {
    EXPECT_FALSE(is_safe_bundle_path(bad)) << bad;
  }
  EXPECT_FALSE(is_safe_bundle_path(std::string("a\0b", 3)));
  EXPECT_FALSE(is_safe_bundle_path("a\nb"));
  EXPECT_FALSE(is_safe_bundle_path(std::string(256, 'x')));  // one component over NAME_MAX
  EXPECT_TRUE(is_safe_bundle_path(std::string(255, 'x')));
}

TEST(Bundle, ParseRefusesEachBadShapeNamingTheEntry) {
  EXPECT_EQ(refusal(bundle("s.json", {"s.json", "m/x.obj"})), "");
  EXPECT_NE(refusal("\xff\xff\xff").find("not a tessera.v1.Bundle"), std::string::npos);
  EXPECT_NE(refusal(bundle("s.json", {"s.json", "../x"})).find("'../x' is not a safe relative path"), std::string::npos);
  EXPECT_NE(refusal(bundle("/s.json", {"/s.json"})).find("scene_file '/s.json'"), std::string::npos);
  EXPECT_NE(refusal(bundle("s.json", {"s.json", "s.json"})).find("'s.json' appears twice"), std::string::npos);
  EXPECT_NE(refusal(bundle("a", {"a", "a/b/c"})).find("'a' is both a file and the directory of 'a/b/c'"),
            std::string::npos);
  EXPECT_NE(refusal(bundle("s.json", {"t.json"})).find("does not contain its scene file 's.json'"), std::string::npos);
}

}  // namespace
}  // namespace tessera::farm

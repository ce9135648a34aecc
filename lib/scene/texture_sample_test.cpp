// SPDX-License-Identifier: Apache-2.0
// Texture lookup against hand-computed values: texel centers, bilinear blends, wrap modes.
#include "scene/texture_sample.h"

#include <gtest/gtest.h>

namespace tessera {
namespace {

Texture two_texels(Texture::Wrap wrap, bool nearest = false) {
  Texture t;
  t.width = 2;
  t.height = 1;
  t.texels = std::make_shared<std::vector<Rgb>>(std::vector<Rgb>{Rgb(0.0f), Rgb(1.0f)});
  t.wrap_s = t.wrap_t = wrap;
  t.nearest = nearest;
  return t;
}

TEST(TextureSample, BilinearIsExactAtTexelCentersAndBlendsBetween) {
  const Texture t = two_texels(Texture::Wrap::kClamp);
  EXPECT_EQ(sample_texture(t, 0.25, 0.5).x, 0.0f);   // center of texel 0
  EXPECT_EQ(sample_texture(t, 0.75, 0.5).x, 1.0f);   // center of texel 1
  EXPECT_EQ(sample_texture(t, 0.5, 0.5).x, 0.5f);    // half way
  EXPECT_EQ(sample_texture(t, 0.625, 0.5).x, 0.75f);
  EXPECT_EQ(sample_texture(t, 0.0, 0.5).x, 0.0f);    // clamped at the edge
}

TEST(TextureSample, WrapModesAtTheEdge) {
  // u = 0: half way between texel -1 and texel 0.
  EXPECT_EQ(sample_texture(two_texels(Texture::Wrap::kRepeat), 0.0, 0.5).x, 0.5f);  // texel -1 is texel 1
  EXPECT_EQ(sample_texture(two_texels(Texture::Wrap::kMirror), 0.0, 0.5).x, 0.0f);  // texel -1 is texel 0
  EXPECT_EQ(sample_texture(two_texels(Texture::Wrap::kRepeat), 1.25, 0.5).x, 0.0f);
  EXPECT_EQ(sample_texture(two_texels(Texture::Wrap::kMirror), 1.25, 0.5).x, 1.0f);  // mirrored: texel 2 is texel 1
}

TEST(TextureSample, NearestTakesTheTexelUnderTheCoordinate) {
  const Texture t = two_texels(Texture::Wrap::kRepeat, true);
  EXPECT_EQ(sample_texture(t, 0.49, 0.5).x, 0.0f);
  EXPECT_EQ(sample_texture(t, 0.51, 0.5).x, 1.0f);
  EXPECT_EQ(sample_texture(t, -0.25, 0.5).x, 1.0f);  // repeat
}

}  // namespace
}  // namespace tessera

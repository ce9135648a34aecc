// Tile decoding as the client does it: a rectangle from the network must fit the image, with no
// integer overflow in the check.
#include "farm/codec.h"

#include <gtest/gtest.h>

#include <climits>

namespace tessera::farm {
namespace {

tessera::v1::TileData tile(int x0, int y0, int w, int h) {
  tessera::v1::TileData t;
  t.mutable_rect()->set_x0(x0);
  t.mutable_rect()->set_y0(y0);
  t.mutable_rect()->set_width(w);
  t.mutable_rect()->set_height(h);
  t.set_rgb(std::string(size_t(w) * size_t(h) * 12, '\0'));
  t.set_variance(std::string(size_t(w) * size_t(h) * 4, '\0'));
  return t;
}

TEST(Codec, TileMustFitTheImage) {
  TileResult r;
  EXPECT_EQ(decode_tile_in_image(tile(60, 44, 4, 4), 64, 48, &r), "");  // touches the corner
  EXPECT_EQ(r.rgb.size(), 48u);
  EXPECT_NE(decode_tile_in_image(tile(61, 0, 4, 4), 64, 48, &r), "");
  EXPECT_NE(decode_tile_in_image(tile(0, 45, 4, 4), 64, 48, &r), "");
  EXPECT_NE(decode_tile_in_image(tile(-1, 0, 4, 4), 64, 48, &r), "");
  // x0 + width overflows int: 32-bit arithmetic would wrap negative and pass.
  const std::string err = decode_tile_in_image(tile(INT_MAX - 1, 0, 4, 4), 64, 48, &r);
  EXPECT_NE(err.find("outside the 64x48 image"), std::string::npos) << err;
  EXPECT_NE(decode_tile_in_image(tile(0, INT_MAX - 1, 4, 4), 64, 48, &r), "");
}

TEST(Codec, SizesMustMatchTheRectangle) {
  TileResult r;
  auto t = tile(0, 0, 4, 4);
  t.mutable_rgb()->pop_back();
  EXPECT_NE(decode_tile(t, &r).find("rgb has 191 bytes, expected 192"), std::string::npos);
  EXPECT_NE(check_tile(tile(0, 0, 0, 4), 0, 4), "");
}

}  // namespace
}  // namespace tessera::farm

// Tile decoding as the client does it: a rectangle from the network must fit the image, with no
// integer overflow in the check.
#include "farm/overrides_codec.h"
#include "farm/tile_codec.h"

#include <gtest/gtest.h>

#include <climits>
#include <cmath>

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

// A job's glTF options: only what differs from the defaults goes on the wire (so a job without
// them keeps the overrides it had before they existed), values come back unchanged, and values
// out of range from a peer that skipped the client's checks are refused naming the field.
TEST(Codec, GltfOptionsRoundTripAndBadValuesNameTheField) {
  tessera::v1::ImageOverrides none;
  to_proto(GltfOptions{}, &none);
  EXPECT_EQ(none.ByteSizeLong(), 0u);
  GltfOptions g;
  g.camera = "side";
  g.scene_index = 0;  // given, though it may equal the file's default
  g.fps = 12.5;
  tessera::v1::ImageOverrides o;
  to_proto(g, &o);
  const GltfOptions back = gltf_options_from_proto(o);
  EXPECT_EQ(back.camera, "side");
  EXPECT_EQ(back.scene_index, 0);
  EXPECT_EQ(back.fps, 12.5);
  EXPECT_TRUE(back.given());
  auto error = [](const tessera::v1::ImageOverrides& bad) -> std::string {
    try {
      gltf_options_from_proto(bad);
    } catch (const SceneError& e) {
      return e.what();
    }
    return "accepted";
  };
  tessera::v1::ImageOverrides bad = o;
  bad.set_gltf_scene_index(-1);
  EXPECT_EQ(error(bad), "overrides.gltf_scene_index: must be >= 0, got -1");
  for (double fps : {0.0, -3.0, 1000.5, std::nan("")}) {
    bad = o;
    bad.set_gltf_fps(fps);
    EXPECT_NE(error(bad).find("overrides.gltf_fps: must be in (0, 1000]"), std::string::npos) << fps;
  }
  bad = o;
  bad.set_gltf_fps(1000);
  EXPECT_EQ(error(bad), "accepted");
}

}  // namespace
}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
// Tile decoding as the client does it: a rectangle from the network must fit the image, with no
// integer overflow in the check.
#include "farm/overrides_codec.h"
#include "farm/tile_codec.h"

#include <gtest/gtest.h>

#include <bit>
#include <climits>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

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

// The roulette's weight crosses the wire as given (0 included: "trace every branch" is a value,
// not an absent field), and the worker's apply_overrides refuses what the CLI would.
TEST(Codec, RouletteWeightOverrideRoundTripsAndIsCheckedWhereItIsApplied) {
  ImageOverrides o;
  o.roulette_weight = 0.0;
  tessera::v1::ImageOverrides wire;
  to_proto(o, &wire);
  ASSERT_TRUE(wire.has_roulette_weight());
  const ImageOverrides back = from_proto(wire);
  ASSERT_TRUE(back.roulette_weight.has_value());
  EXPECT_EQ(*back.roulette_weight, 0.0);
  EXPECT_FALSE(from_proto(tessera::v1::ImageOverrides{}).roulette_weight.has_value());
  Scene s = parse_scene(R"({"camera": {"position": [0, 0, 1], "look_at": [0, 0, 0]}, "materials": {}, "objects": []})",
                        "ok.json");
  apply_overrides(s, back);
  EXPECT_EQ(s.image.roulette_weight, 0.0);
  for (double bad : {-0.5, 1.5, std::nan("")}) {
    wire.set_roulette_weight(bad);
    try {
      apply_overrides(s, from_proto(wire));
      ADD_FAILURE() << bad << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("--roulette-weight: must be in [0, 1]"), std::string::npos) << e.what();
    }
  }
}

TileResult rendered_tile(int w, int h, bool uniform_spp) {
  TileResult t;
  t.rect = {8, 4, w, h};
  const size_t px = size_t(w) * size_t(h);
  for (size_t i = 0; i < 3 * px; ++i) t.rgb.push_back(std::ldexp(float(i % 97) + 0.123456789f, int(i % 40) - 20));
  for (size_t i = 0; i < px; ++i) {
    t.variance.push_back(std::ldexp(1.0f + float(i) / float(px), int(i % 200) - 100));  // 2^-100 .. 2^100
    t.spp.push_back(uniform_spp ? 16u : uint32_t(4 + i % 61));
  }
  return t;
}

// Pixels cross the wire bit for bit; the variance as bfloat16 keeps float32's range and is
// within half a unit in the 8th significant bit (relative 2^-8) of the worker's value; sample
// counts come back exactly, whether sent per pixel or once for the tile.
TEST(Codec, EncodeDecodeKeepsPixelsExactAndTheVarianceWithinBfloat16Rounding) {
  for (bool uniform : {true, false}) {
    const TileResult in = rendered_tile(32, 17, uniform);
    tessera::v1::TileData d;
    encode_tile(in, &d);
    EXPECT_TRUE(d.variance().empty());
    EXPECT_EQ(d.variance_bf16().size(), in.variance.size() * 2);
    EXPECT_EQ(d.spp().size(), uniform ? 0u : in.spp.size() * 4);
    EXPECT_EQ(d.uniform_spp(), uniform ? 16u : 0u);
    EXPECT_EQ(validate_tile(d, in.rect), "");
    TileResult out;
    ASSERT_EQ(decode_tile(d, &out), "");
    ASSERT_EQ(out.rgb.size(), in.rgb.size());
    EXPECT_EQ(std::memcmp(out.rgb.data(), in.rgb.data(), in.rgb.size() * 4), 0);
    EXPECT_EQ(out.spp, in.spp);
    ASSERT_EQ(out.variance.size(), in.variance.size());
    for (size_t i = 0; i < in.variance.size(); ++i) {
      ASSERT_LE(std::abs(out.variance[i] - in.variance[i]), std::ldexp(in.variance[i], -8)) << i;
    }
  }
}

TEST(Codec, Bfloat16VarianceNeverTurnsInfiniteAndNaNIsRefused) {
  TileResult t = rendered_tile(4, 4, true);
  t.variance[0] = std::numeric_limits<float>::max();  // rounds up past bfloat16's largest: truncated
  t.variance[1] = 0.0f;
  t.variance[2] = std::numeric_limits<float>::denorm_min();
  tessera::v1::TileData d;
  encode_tile(t, &d);
  EXPECT_EQ(validate_tile(d, t.rect), "");
  TileResult out;
  ASSERT_EQ(decode_tile(d, &out), "");
  EXPECT_TRUE(std::isfinite(out.variance[0]));
  EXPECT_GE(out.variance[0], std::ldexp(1.0f, 127));
  EXPECT_EQ(out.variance[1], 0.0f);
  t.variance[5] = std::nanf("");
  encode_tile(t, &d);
  EXPECT_EQ(validate_tile(d, t.rect), "variance of pixel (9, 5) is NaN");
  t.variance[5] = std::numeric_limits<float>::infinity();
  encode_tile(t, &d);
  EXPECT_EQ(validate_tile(d, t.rect), "variance of pixel (9, 5) is infinite");
}

// Statistics a hostile or broken worker could send are refused naming the value: a negative
// variance (in either encoding; -0 is zero and fine), a render time that is NaN or negative, ray
// counts past any render, more nonfinite samples than samples.
TEST(Codec, ValidateRefusesStatisticsNoRenderProduces) {
  TileResult t = rendered_tile(4, 4, true);
  t.variance[0] = -0.0f;
  tessera::v1::TileData d;
  encode_tile(t, &d);
  EXPECT_EQ(validate_tile(d, t.rect), "");
  t.variance[6] = -0.25f;
  encode_tile(t, &d);
  EXPECT_EQ(validate_tile(d, t.rect), "variance of pixel (10, 5) is negative (-0.250000)");
  auto f32 = tile(8, 4, 4, 4);
  const float minus = -1.0f;
  std::memcpy(f32.mutable_variance()->data() + 4 * 3, &minus, 4);
  EXPECT_EQ(validate_tile(f32, t.rect), "variance of pixel (11, 4) is negative (-1.000000)");

  t = rendered_tile(4, 4, true);
  encode_tile(t, &d);
  auto bad = d;
  bad.set_seconds(std::nan(""));
  EXPECT_EQ(validate_tile(bad, t.rect), "render time nan s is not a finite duration >= 0");
  bad.set_seconds(-1);
  EXPECT_EQ(validate_tile(bad, t.rect), "render time -1.000000 s is not a finite duration >= 0");
  bad = d;
  bad.mutable_rays()->set_shadow(kMaxRaysPerTile + 1);
  EXPECT_EQ(validate_tile(bad, t.rect), "shadow ray count 1099511627777 is above 1099511627776 per tile");
  bad = d;
  bad.mutable_rays()->set_camera(16);
  bad.mutable_rays()->set_nonfinite_samples(17);
  EXPECT_EQ(validate_tile(bad, t.rect), "nonfinite_samples 17 is above the camera ray count 16");
  bad.mutable_rays()->set_camera(kMaxRaysPerTile);  // at the bound: accepted
  EXPECT_EQ(validate_tile(bad, t.rect), "");
}

// Every field TileData defines survives known_fields_only (set through reflection, so a field
// added to the message and not to the function fails here); unknown fields, at the top and in
// the nested messages, do not; the bytes are moved, not copied.
TEST(Codec, BlockStatisticsCrossTheWireBitForBitAndBadOnesAreNamed) {
  // The coordinator plans from what workers report: every field the planner reads, bit for bit
  // (its plan must be the one `tessera render` makes from the same numbers).
  BlockStat a;
  a.block = (int64_t(1) << 40) + 3;
  a.spp = 1024;
  a.pixels = 4;
  a.mse = 1.0 / 3.0;
  a.shape_mse = std::nextafter(a.mse, 1.0);
  a.cost = 2.75;
  a.mean = {-0.0f, std::numeric_limits<float>::denorm_min(), 65504.5f};
  BlockStat b = a;
  b.block = 0;
  b.mean = {0.25f, 0.45f, 0.8f};
  std::vector<BlockStat> back;
  const std::string bytes = encode_block_stats({a, b});
  EXPECT_EQ(bytes.size(), 2u * 52u);
  ASSERT_EQ(decode_block_stats(bytes, &back), "");
  ASSERT_EQ(back.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const BlockStat& want = i == 0 ? a : b;
    EXPECT_EQ(back[i].block, want.block);
    EXPECT_EQ(back[i].spp, want.spp);
    EXPECT_EQ(back[i].pixels, want.pixels);
    EXPECT_EQ(std::memcmp(&back[i].mse, &want.mse, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&back[i].shape_mse, &want.shape_mse, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&back[i].cost, &want.cost, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(back[i].mean.data(), want.mean.data(), sizeof(float) * 3), 0) << i;
  }
  EXPECT_TRUE(std::signbit(back[0].mean[0]));
  // Little-endian whatever the host: the mean's R of block b starts at byte 52 + 40.
  uint32_t r = 0;
  for (int k = 0; k < 4; ++k) r |= uint32_t(uint8_t(bytes[52 + 40 + size_t(k)])) << (8 * k);
  EXPECT_EQ(r, std::bit_cast<uint32_t>(0.25f));

  auto refused = [&](std::function<void(BlockStat&)> spoil, const std::string& why) {
    BlockStat bad = a;
    spoil(bad);
    const std::string err = decode_block_stats(encode_block_stats({b, bad}), &back);
    EXPECT_NE(err.find("block_stats[1]"), std::string::npos) << err;
    EXPECT_NE(err.find(why), std::string::npos) << err;
  };
  refused([](BlockStat& s) { s.mean[1] = std::numeric_limits<float>::quiet_NaN(); }, "mean G is not finite");
  refused([](BlockStat& s) { s.mean[2] = std::numeric_limits<float>::infinity(); }, "mean B is not finite");
  refused([](BlockStat& s) { s.shape_mse = s.mse / 2; }, "shape_mse is below mse");
  refused([](BlockStat& s) { s.block = -1; }, "negative block index");
  EXPECT_NE(decode_block_stats(bytes.substr(0, 40), &back).find("not a multiple of 52"), std::string::npos);
}

TEST(Codec, KnownFieldsOnlyKeepsEveryFieldTileDataDefines) {
  tessera::v1::TileData in;
  std::function<void(google::protobuf::Message*, int)> fill = [&](google::protobuf::Message* m, int seed) {
    const auto* desc = m->GetDescriptor();
    const auto* r = m->GetReflection();
    for (int i = 0; i < desc->field_count(); ++i) {
      const auto* f = desc->field(i);
      ASSERT_FALSE(f->is_repeated()) << f->full_name() << ": extend this test and known_fields_only";
      const int v = seed + i + 1;
      using FD = google::protobuf::FieldDescriptor;
      switch (f->cpp_type()) {
        case FD::CPPTYPE_INT32: r->SetInt32(m, f, v); break;
        case FD::CPPTYPE_UINT32: r->SetUInt32(m, f, uint32_t(v)); break;
        case FD::CPPTYPE_INT64: r->SetInt64(m, f, v); break;
        case FD::CPPTYPE_UINT64: r->SetUInt64(m, f, uint64_t(v)); break;
        case FD::CPPTYPE_DOUBLE: r->SetDouble(m, f, v + 0.5); break;
        case FD::CPPTYPE_STRING: r->SetString(m, f, std::string(size_t(v) + 32, char('a' + v % 26))); break;
        case FD::CPPTYPE_MESSAGE: fill(r->MutableMessage(m, f), 100 * v); break;
        default: FAIL() << f->full_name() << ": a field type this test does not set";
      }
    }
  };
  fill(&in, 0);
  const std::string known = in.SerializeAsString();
  const auto unknown = [](google::protobuf::Message* m) { return m->GetReflection()->MutableUnknownFields(m); };
  unknown(&in)->AddLengthDelimited(999, std::string(1 << 20, 'x'));
  unknown(in.mutable_rect())->AddVarint(77, 5);
  unknown(in.mutable_rays())->AddLengthDelimited(78, "padding");
  const char* rgb = in.rgb().data();
  const tessera::v1::TileData out = known_fields_only(std::move(in));
  EXPECT_EQ(out.SerializeAsString(), known);
  EXPECT_EQ(out.rgb().data(), rgb) << "the pixel bytes were copied, not moved";
}

// A peer that sends the variance as float32 (older workers, other implementations) is still
// read; one that sends both, or a wrong size, is refused naming the field.
TEST(Codec, Float32VarianceIsStillReadAndBadSizesAreNamed) {
  TileResult r;
  auto t = tile(0, 0, 4, 4);
  ASSERT_EQ(decode_tile(t, &r), "");
  EXPECT_EQ(r.variance.size(), 16u);
  EXPECT_TRUE(r.spp.empty());  // no counts said: the client assumes the job's spp
  t.set_variance_bf16(std::string(32, '\0'));
  EXPECT_EQ(decode_tile(t, &r), "tile has both variance and variance_bf16");
  t.clear_variance();
  EXPECT_EQ(decode_tile(t, &r), "");
  t.mutable_variance_bf16()->pop_back();
  EXPECT_EQ(decode_tile(t, &r), "tile variance_bf16 has 31 bytes, expected 32");
  t.clear_variance_bf16();
  EXPECT_EQ(decode_tile(t, &r), "tile has no variance (variance_bf16: 32 bytes, or variance: 64)");
}

}  // namespace
}  // namespace tessera::farm

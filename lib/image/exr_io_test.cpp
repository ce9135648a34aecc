// SPDX-License-Identifier: Apache-2.0
#include "image/exr_io.h"

#include <ImfCompression.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace tessera {
namespace {

TEST(ExrIo, FloatRoundTripIsExactAndKeepsAttributes) {
  ImageRGB img(7, 5);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = std::ldexp(float(i) + 0.1f, int(i % 40) - 20);
  img.rgb[4] = 160.0f;
  img.rgb[5] = 1e-30f;
  const auto path = std::filesystem::temp_directory_path() / "tessera_exr_io_test.exr";
  write_exr(path.string(), img, {{"renderer", std::string("tessera")}, {"spp", int64_t(16)},
                                 {"renderTimeSeconds", 1.25}});
  ExrAttributes attrs;
  const ImageRGB back = read_exr(path.string(), &attrs);
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  EXPECT_EQ(back.rgb, img.rgb);
  EXPECT_EQ(std::get<std::string>(attrs.at("renderer")), "tessera");
  EXPECT_EQ(std::get<int64_t>(attrs.at("spp")), 16);
  EXPECT_DOUBLE_EQ(std::get<double>(attrs.at("renderTimeSeconds")), 1.25);
  std::filesystem::remove(path);
}

// Many ZIP line blocks (16 rows each), compressed on one thread and on four: the same bytes, and
// they read back exactly with either count.
TEST(ExrIo, TheBytesDoNotDependOnTheThreadCount) {
  ImageRGB img(61, 203);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = std::sin(float(i) * 0.37f) * float(i % 97);
  const std::vector<float> extra(img.pixel_count(), 3.5f);
  const auto dir = std::filesystem::temp_directory_path();
  auto bytes = [](const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  std::string written[2];
  for (int k = 0; k < 2; ++k) {
    set_exr_threads(k == 0 ? 1 : 4);
    const auto path = dir / ("tessera_exr_threads_" + std::to_string(k) + ".exr");
    write_exr(path.string(), img, {{"spp", int64_t(4)}}, ExrPixelType::kFloat, {{"error.Y", &extra}});
    written[k] = bytes(path);
    set_exr_threads(k == 0 ? 4 : 1);
    EXPECT_EQ(read_exr(path.string()).rgb, img.rgb);
    EXPECT_EQ(read_exr_channel(path.string(), "error.Y"), extra);
    std::filesystem::remove(path);
  }
  set_exr_threads(0);
  ASSERT_GT(written[0].size(), 1000u);
  EXPECT_EQ(written[0], written[1]);
}

// Every compression the command line offers is lossless: float bits come back as written
// (denormals, -0, the largest float, NaN payloads), in the R, G, B channels and the extra ones,
// and the file says the compression it was asked for (read by OpenEXR's own header reader).
TEST(ExrIo, EveryCompressionIsLosslessAndIsTheOneAskedFor) {
  ImageRGB img(37, 41);  // more rows than a ZIP block (16) or a PIZ block (32)
  uint32_t x = 12345;
  for (float& v : img.rgb) {
    x = x * 1664525u + 1013904223u;  // every bit pattern, NaNs and infinities included
    std::memcpy(&v, &x, sizeof v);
  }
  img.rgb[0] = -0.0f;
  img.rgb[1] = std::numeric_limits<float>::denorm_min();
  img.rgb[2] = std::numeric_limits<float>::max();
  std::vector<float> extra(img.pixel_count());
  for (size_t i = 0; i < extra.size(); ++i) extra[i] = float(i % 7) * 0.25f;
  const auto bits = [](const std::vector<float>& v) {
    return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float));
  };
  ASSERT_EQ(exr_compression_names().size(), 5u);
  for (const std::string& name : exr_compression_names()) {
    SCOPED_TRACE(name);
    const ExrCompression c = parse_exr_compression(name);
    EXPECT_EQ(exr_compression_name(c), name);
    const auto path = std::filesystem::temp_directory_path() / ("tessera_exr_compression_" + name + ".exr");
    write_exr(path.string(), img, {}, ExrPixelType::kFloat, {{"error.Y", &extra}}, c);
    EXPECT_EQ(bits(read_exr(path.string()).rgb), bits(img.rgb));
    EXPECT_EQ(bits(read_exr_channel(path.string(), "error.Y")), bits(extra));
    const std::map<std::string, Imf::Compression> in_the_file{{"none", Imf::NO_COMPRESSION},
                                                               {"rle", Imf::RLE_COMPRESSION},
                                                               {"zips", Imf::ZIPS_COMPRESSION},
                                                               {"zip", Imf::ZIP_COMPRESSION},
                                                               {"piz", Imf::PIZ_COMPRESSION}};
    EXPECT_EQ(Imf::InputFile(path.string().c_str()).header().compression(), in_the_file.at(name));
    std::filesystem::remove(path);
  }
}

TEST(ExrIo, AnUnknownOrLossyCompressionIsRefusedWithTheAllowedNames) {
  for (const char* name : {"dwaa", "pxr24", "b44", "ZIP", ""}) {
    try {
      parse_exr_compression(name);
      ADD_FAILURE() << name << " was accepted";
    } catch (const ExrError& e) {
      EXPECT_NE(std::string(e.what()).find("allowed: none, rle, zips, zip, piz"), std::string::npos) << e.what();
    }
  }
}

TEST(ExrIo, HalfClampsInsteadOfWritingInf) {
  ImageRGB img(2, 1);
  img.rgb = {1e6f, -1e6f, NAN, 1.0f, 0.5f, 65504.0f};
  const auto path = std::filesystem::temp_directory_path() / "tessera_exr_half_test.exr";
  write_exr(path.string(), img, {}, ExrPixelType::kHalf);
  const ImageRGB back = read_exr(path.string());
  EXPECT_EQ(back.rgb[0], 65504.0f);
  EXPECT_EQ(back.rgb[1], -65504.0f);
  EXPECT_EQ(back.rgb[2], 0.0f);
  EXPECT_EQ(back.rgb[3], 1.0f);
  EXPECT_EQ(back.rgb[5], 65504.0f);
  std::filesystem::remove(path);
}

TEST(ExrIo, MissingFileNamesThePath) {
  try {
    read_exr("/nonexistent/dir/x.exr");
    FAIL() << "expected ExrError";
  } catch (const ExrError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/x.exr"), std::string::npos);
  }
}

}  // namespace
}  // namespace tessera

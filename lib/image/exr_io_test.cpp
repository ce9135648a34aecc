#include "image/exr_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

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

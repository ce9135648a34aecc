// SPDX-License-Identifier: Apache-2.0
#include "color/palette_quantizer.h"

#include <gtest/gtest.h>

#include <random>

#include "color/image_metrics.h"
#include "color/srgb.h"
#include "support/synthetic_images.h"
#include "color/tonemap.h"

namespace tessera::color {
namespace {

ImageRGB decode_srgb(const IndexedImage& q) {
  ImageRGB out(q.width, q.height);
  for (size_t i = 0; i < q.indices.size(); ++i) {
    const Srgb8& c = q.palette[q.indices[i]];
    out.rgb[3 * i] = float(c.r) / 255.0f;
    out.rgb[3 * i + 1] = float(c.g) / 255.0f;
    out.rgb[3 * i + 2] = float(c.b) / 255.0f;
  }
  return out;
}

ImageRGB decode_linear(const IndexedImage& q) {
  ImageRGB out(q.width, q.height);
  for (size_t i = 0; i < q.indices.size(); ++i) {
    const Rgb c = srgb8_to_linear(q.palette[q.indices[i]]);
    for (int k = 0; k < 3; ++k) out.rgb[3 * i + size_t(k)] = c[k];
  }
  return out;
}

double psnr(const ImageRGB& display_linear, const IndexedImage& q) {
  return ldr_error(srgb_encode_image(display_linear), decode_srgb(q)).psnr_db;
}

TEST(Oklab, WhiteBlackAndRoundTrip) {
  const Oklab white = linear_srgb_to_oklab({1.0f, 1.0f, 1.0f});
  EXPECT_NEAR(white.L, 1.0f, 1e-4);
  EXPECT_NEAR(white.a, 0.0f, 1e-4);
  EXPECT_NEAR(white.b, 0.0f, 1e-4);
  EXPECT_EQ(linear_srgb_to_oklab({}).L, 0.0f);
  // Ottosson's reference value for linear sRGB red: L 0.62796, a 0.22486, b 0.12585.
  const Oklab red = linear_srgb_to_oklab({1.0f, 0.0f, 0.0f});
  EXPECT_NEAR(red.L, 0.62796, 1e-4);
  EXPECT_NEAR(red.a, 0.22486, 1e-4);
  EXPECT_NEAR(red.b, 0.12585, 1e-4);
  const Rgb back = oklab_to_linear_srgb(linear_srgb_to_oklab({0.2f, 0.7f, 0.05f}));
  EXPECT_NEAR(back.r, 0.2f, 1e-5);
  EXPECT_NEAR(back.g, 0.7f, 1e-5);
  EXPECT_NEAR(back.b, 0.05f, 1e-5);
}

TEST(PaletteQuantizer, NearestSearchMatchesBruteForce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Oklab> palette;
  for (int i = 0; i < 200; ++i) palette.push_back(linear_srgb_to_oklab({u(rng), u(rng), u(rng)}));
  const OklabNearest search(palette);
  for (int q = 0; q < 5000; ++q) {
    const Oklab c = linear_srgb_to_oklab({u(rng), u(rng), u(rng)});
    int best = 0;
    for (int i = 1; i < 200; ++i) {
      if (oklab_distance2(palette[size_t(i)], c) < oklab_distance2(palette[size_t(best)], c)) best = i;
    }
    ASSERT_EQ(oklab_distance2(palette[size_t(search.nearest(c))], c),
              oklab_distance2(palette[size_t(best)], c));
  }
}

TEST(PaletteQuantizer, NeverMoreColorsThanAsked) {
  ImageRGB noise(96, 64);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (float& v : noise.rgb) v = u(rng);
  for (int n : {2, 3, 7, 16, 64, 200, 256}) {
    for (auto d : {DitherMethod::kNone, DitherMethod::kFloydSteinberg}) {
      const IndexedImage q = quantize_palette(noise, {n, d, 16});
      EXPECT_LE(int(q.palette.size()), n);
      EXPECT_GE(int(q.palette.size()), std::min(n, 2));
      for (uint8_t i : q.indices) ASSERT_LT(i, q.palette.size());
    }
  }
  EXPECT_THROW(quantize_palette(noise, {1, DitherMethod::kNone, 16}), std::exception);
  EXPECT_THROW(quantize_palette(noise, {257, DitherMethod::kNone, 16}), std::exception);
}

TEST(PaletteQuantizer, FewColorsAreKeptExactly) {
  ImageRGB img(40, 10);
  for (int i = 0; i < 400; ++i) {
    const float v = float(srgb8_to_linear_table()[size_t((i % 10) * 25)]);
    img.rgb[size_t(3 * i)] = v;
    img.rgb[size_t(3 * i + 1)] = 1.0f - v;
    img.rgb[size_t(3 * i + 2)] = 0.5f;
  }
  const IndexedImage q = quantize_palette(img, {16, DitherMethod::kNone, 16});
  EXPECT_EQ(q.palette.size(), 10u);
  EXPECT_LE(ldr_error(srgb_encode_image(img), decode_srgb(q)).max_abs, 0.5);  // only 8-bit rounding
}

TEST(PaletteQuantizer, SmoothGradientReaches38DbAt256Colors) {
  const ImageRGB img = make_smooth_gradient(320, 240);
  const IndexedImage q = quantize_palette(img, {256, DitherMethod::kNone, 16});
  EXPECT_GE(psnr(img, q), 38.0);
}

TEST(PaletteQuantizer, RenderLikeFrameReaches38DbAt256Colors) {
  const ImageRGB hdr = make_render_like(320, 240);
  for (auto op : {ToneMapOperator::kAces, ToneMapOperator::kPbrNeutral}) {
    const ImageRGB display = tonemap_image(hdr, {op, 0.0f, 0.0f});
    const IndexedImage q = quantize_palette(display, {256, DitherMethod::kNone, 16});
    EXPECT_GE(psnr(display, q), 38.0) << tonemap_name(op);
  }
}

TEST(PaletteQuantizer, FloydSteinbergReducesBanding) {
  // A slow warm ramp, the case where 16 colors band visibly.
  ImageRGB img(256, 64);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const float v = 0.02f + 0.25f * float(x) / 255.0f;
      float* p = img.at(x, y);
      p[0] = v;
      p[1] = v * 0.8f;
      p[2] = v * 0.6f;
    }
  }
  const IndexedImage plain = quantize_palette(img, {16, DitherMethod::kNone, 16});
  const IndexedImage fs = quantize_palette(img, {16, DitherMethod::kFloydSteinberg, 16});
  EXPECT_EQ(plain.palette, fs.palette);  // same palette, only the mapping differs
  // Banding as low-frequency error (9x9 box) in linear light, away from the ramp's ends
  // (k-means centroids sit inside the colors they stand for, so the extremes are missed by
  // both mappings alike) ...
  auto middle = [](const ImageRGB& im) {
    ImageRGB out(im.width / 2, im.height);
    for (int y = 0; y < out.height; ++y) {
      for (int x = 0; x < out.width; ++x) {
        for (int c = 0; c < 3; ++c) out.at(x, y)[c] = im.at(x + im.width / 4, y)[c];
      }
    }
    return out;
  };
  const double band_plain = low_frequency_error(middle(img), middle(decode_linear(plain)), 4);
  const double band_fs = low_frequency_error(middle(img), middle(decode_linear(fs)), 4);
  EXPECT_LT(band_fs, 0.5 * band_plain) << band_plain << " " << band_fs;
  // ... and as flat runs along a row: without dither, at most 16 long steps.
  auto runs = [](const IndexedImage& q, int y) {
    int n = 1;
    for (int x = 1; x < q.width; ++x) {
      n += q.indices[size_t(y * q.width + x)] != q.indices[size_t(y * q.width + x - 1)];
    }
    return n;
  };
  EXPECT_LE(runs(plain, 32), 16);
  EXPECT_GT(runs(fs, 32), 4 * runs(plain, 32));
}

TEST(PaletteQuantizer, IsDeterministic) {
  const ImageRGB img = make_render_like(120, 80);
  const ImageRGB display = tonemap_image(img, {ToneMapOperator::kAces, 0.0f, 0.0f});
  const IndexedImage a = quantize_palette(display, {64, DitherMethod::kFloydSteinberg, 16});
  const IndexedImage b = quantize_palette(display, {64, DitherMethod::kFloydSteinberg, 16});
  EXPECT_EQ(a.palette, b.palette);
  EXPECT_EQ(a.indices, b.indices);
}

}  // namespace
}  // namespace tessera::color

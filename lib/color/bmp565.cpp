// SPDX-License-Identifier: Apache-2.0
#include "color/bmp565.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>

#include "color/color_error.h"
#include "color/little_endian.h"

namespace tessera::color {

namespace {

constexpr uint32_t kBiBitfields = 3;
constexpr uint32_t kLcsSrgb = 0x73524742;  // 'sRGB'
constexpr uint32_t kFileHeaderBytes = 14, kV4HeaderBytes = 108;
constexpr uint32_t kRedMask = 0xF800, kGreenMask = 0x07E0, kBlueMask = 0x001F;

uint32_t quantize(float v, int levels, float threshold) {
  if (!(v > 0.0f)) return 0;  // NaN too
  const float q = std::floor(v * float(levels) + threshold);
  return uint32_t(std::clamp(q, 0.0f, float(levels)));
}

size_t row_stride(int width) { return (size_t(width) * 2 + 3) & ~size_t(3); }

}  // namespace

uint16_t pack_565(const Rgb& c, float threshold) {
  return uint16_t(quantize(c.r, 31, threshold) << 11 | quantize(c.g, 63, threshold) << 5 |
                  quantize(c.b, 31, threshold));
}

Rgb unpack_565(uint16_t p) {
  return {float(p >> 11) / 31.0f, float((p >> 5) & 63) / 63.0f, float(p & 31) / 31.0f};
}

std::vector<uint16_t> quantize_565(const ImageRGB& img, DitherMethod dither) {
  if (dither == DitherMethod::kFloydSteinberg) {
    throw ColorError("rgb565 supports --dither none, bayer or blue-noise");
  }
  std::vector<uint16_t> out(img.pixel_count());
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const float* p = img.at(x, y);
      out[size_t(y) * size_t(img.width) + size_t(x)] =
          pack_565({p[0], p[1], p[2]}, ordered_threshold(dither, x, y));
    }
  }
  return out;
}

void write_bmp565(const std::string& path, int width, int height,
                  const std::vector<uint16_t>& pixels) {
  if (width <= 0 || height <= 0 || pixels.size() != size_t(width) * size_t(height)) {
    throw ColorError("cannot write BMP " + path + ": bad image size");
  }
  const size_t stride = row_stride(width);
  const uint32_t image_bytes = uint32_t(stride * size_t(height));
  const uint32_t offset = kFileHeaderBytes + kV4HeaderBytes;
  std::vector<uint8_t> o;
  o.reserve(offset + image_bytes);
  // BITMAPFILEHEADER
  o.push_back('B');
  o.push_back('M');
  put_le32(o, offset + image_bytes);
  put_le32(o, 0);  // reserved
  put_le32(o, offset);
  // BITMAPV4HEADER
  put_le32(o, kV4HeaderBytes);
  put_le32(o, uint32_t(width));
  put_le32(o, uint32_t(height));  // positive: bottom-up rows, the most widely supported order
  put_le16(o, 1);                 // planes
  put_le16(o, 16);                // bits per pixel
  put_le32(o, kBiBitfields);
  put_le32(o, image_bytes);
  put_le32(o, 2835);  // 72 dpi in pixels per meter
  put_le32(o, 2835);
  put_le32(o, 0);  // colors used
  put_le32(o, 0);  // important colors
  put_le32(o, kRedMask);
  put_le32(o, kGreenMask);
  put_le32(o, kBlueMask);
  put_le32(o, 0);  // alpha mask: none
  put_le32(o, kLcsSrgb);
  for (int i = 0; i < 9 + 3; ++i) put_le32(o, 0);  // CIEXYZTRIPLE endpoints, gamma: unused for sRGB
  for (int y = height - 1; y >= 0; --y) {
    const uint16_t* row = &pixels[size_t(y) * size_t(width)];
    for (int x = 0; x < width; ++x) put_le16(o, row[x]);
    for (size_t pad = size_t(width) * 2; pad < stride; ++pad) o.push_back(0);
  }
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(o.data()), std::streamsize(o.size()));
  if (!f) throw ColorError("cannot write BMP " + path);
}

std::vector<uint16_t> read_bmp565(const std::string& path, int* width, int* height) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ColorError("cannot read BMP " + path);
  const std::vector<uint8_t> d((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (d.size() < kFileHeaderBytes + 40 + 12 || d[0] != 'B' || d[1] != 'M') {
    throw ColorError(path + ": not a BMP file");
  }
  const uint32_t offset = get_le32(&d[10]), header = get_le32(&d[14]);
  const int32_t w = int32_t(get_le32(&d[18])), h = int32_t(get_le32(&d[22]));
  if (get_le16(&d[28]) != 16 || get_le32(&d[30]) != kBiBitfields || get_le32(&d[54]) != kRedMask ||
      get_le32(&d[58]) != kGreenMask || get_le32(&d[62]) != kBlueMask || header < 40) {
    throw ColorError(path + ": not a 16-bit 5/6/5 BI_BITFIELDS BMP");
  }
  const int abs_h = h < 0 ? -h : h;
  if (w <= 0 || abs_h == 0 || w > (1 << 16) || abs_h > (1 << 16)) throw ColorError(path + ": bad size");
  const size_t stride = row_stride(w);
  if (d.size() < offset + stride * size_t(abs_h)) throw ColorError(path + ": truncated BMP");
  std::vector<uint16_t> pixels(size_t(w) * size_t(abs_h));
  for (int row = 0; row < abs_h; ++row) {
    const int y = h > 0 ? abs_h - 1 - row : row;
    const uint8_t* src = &d[offset + size_t(row) * stride];
    for (int x = 0; x < w; ++x) pixels[size_t(y) * size_t(w) + size_t(x)] = uint16_t(get_le16(src + 2 * x));
  }
  *width = w;
  *height = abs_h;
  return pixels;
}

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
#include "color/dds_rgb9e5.h"

#include <cstring>
#include <fstream>
#include <iterator>

#include "color/color_error.h"
#include "color/little_endian.h"

namespace tessera::color {

namespace {

// DDS_HEADER flags and caps (Microsoft "DDS_HEADER structure").
constexpr uint32_t kDdsdCaps = 0x1, kDdsdHeight = 0x2, kDdsdWidth = 0x4, kDdsdPitch = 0x8,
                   kDdsdPixelFormat = 0x1000;
constexpr uint32_t kDdpfFourCC = 0x4;
constexpr uint32_t kDdsCapsTexture = 0x1000;
constexpr uint32_t kD3d10ResourceDimensionTexture2D = 3;
constexpr size_t kHeaderBytes = 4 + 124 + 20;  // magic + DDS_HEADER + DDS_HEADER_DXT10

uint32_t fourcc(const char* s) { return get_le32(reinterpret_cast<const uint8_t*>(s)); }

}  // namespace

void write_dds_rgb9e5(const std::string& path, int width, int height,
                      const std::vector<uint32_t>& texels) {
  if (width <= 0 || height <= 0 || texels.size() != size_t(width) * size_t(height)) {
    throw ColorError("cannot write " + path + ": bad image size");
  }
  std::vector<uint8_t> out;
  out.reserve(kHeaderBytes + texels.size() * 4);
  put_le32(out, fourcc("DDS "));
  // DDS_HEADER
  put_le32(out, 124);  // dwSize
  put_le32(out, kDdsdCaps | kDdsdHeight | kDdsdWidth | kDdsdPitch | kDdsdPixelFormat);
  put_le32(out, uint32_t(height));
  put_le32(out, uint32_t(width));
  put_le32(out, uint32_t(width) * 4);  // dwPitchOrLinearSize: bytes per row
  put_le32(out, 0);                    // dwDepth
  put_le32(out, 0);                    // dwMipMapCount (0: the flag is not set, one level)
  for (int i = 0; i < 11; ++i) put_le32(out, 0);  // dwReserved1
  // DDS_PIXELFORMAT: FourCC "DX10" says a DDS_HEADER_DXT10 follows.
  put_le32(out, 32);
  put_le32(out, kDdpfFourCC);
  put_le32(out, fourcc("DX10"));
  for (int i = 0; i < 5; ++i) put_le32(out, 0);  // bit count and masks: unused with FourCC
  put_le32(out, kDdsCapsTexture);                // dwCaps
  for (int i = 0; i < 4; ++i) put_le32(out, 0);  // dwCaps2..4, dwReserved2
  // DDS_HEADER_DXT10
  put_le32(out, kDxgiFormatR9G9B9E5SharedExp);
  put_le32(out, kD3d10ResourceDimensionTexture2D);
  put_le32(out, 0);  // miscFlag
  put_le32(out, 1);  // arraySize
  put_le32(out, 0);  // miscFlags2: alpha mode unknown (there is no alpha)
  for (uint32_t t : texels) put_le32(out, t);  // little-endian words, rows top to bottom

  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(out.data()), std::streamsize(out.size()));
  if (!f) throw ColorError("cannot write DDS " + path);
}

std::vector<uint32_t> read_dds_rgb9e5(const std::string& path, int* width, int* height) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ColorError("cannot read DDS " + path);
  const std::vector<uint8_t> data((std::istreambuf_iterator<char>(f)),
                                  std::istreambuf_iterator<char>());
  if (data.size() < kHeaderBytes || get_le32(&data[0]) != fourcc("DDS ") || get_le32(&data[4]) != 124 ||
      get_le32(&data[80]) != kDdpfFourCC || get_le32(&data[84]) != fourcc("DX10") ||
      get_le32(&data[128]) != kDxgiFormatR9G9B9E5SharedExp ||
      get_le32(&data[132]) != kD3d10ResourceDimensionTexture2D) {
    throw ColorError(path + ": not a DX10 DDS with DXGI_FORMAT_R9G9B9E5_SHAREDEXP");
  }
  const uint32_t h = get_le32(&data[12]), w = get_le32(&data[16]);
  const size_t count = size_t(w) * size_t(h);
  if (w == 0 || h == 0 || w > 1u << 16 || h > 1u << 16 || data.size() < kHeaderBytes + 4 * count) {
    throw ColorError(path + ": truncated DDS");
  }
  std::vector<uint32_t> texels(count);
  for (size_t i = 0; i < count; ++i) texels[i] = get_le32(&data[kHeaderBytes + 4 * i]);
  *width = int(w);
  *height = int(h);
  return texels;
}

}  // namespace tessera::color

// SPDX-License-Identifier: Apache-2.0
// RGB9E5 texels in a DDS file with the DX10 extension header (DXGI_FORMAT_R9G9B9E5_SHAREDEXP
// = 67), the container DirectX, DirectXTex/texconv, NVIDIA Texture Tools and most engines load.
// Hand-written because no Debian library writes DDS; the layout is Microsoft's documented
// DDS_HEADER + DDS_HEADER_DXT10. DDS was picked over KTX2 because neither is readable by the
// oiiotool 2.4 of Debian bookworm, and a DX10 DDS needs no data format descriptor.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace tessera::color {

inline constexpr uint32_t kDxgiFormatR9G9B9E5SharedExp = 67;

// texels: width * height packed RGB9E5 words, top row first. Throws ColorError.
void write_dds_rgb9e5(const std::string& path, int width, int height,
                      const std::vector<uint32_t>& texels);

// Reads back a DX10 DDS holding one 2D R9G9B9E5 image (no mipmaps, arrays or cubes).
std::vector<uint32_t> read_dds_rgb9e5(const std::string& path, int* width, int* height);

}  // namespace tessera::color

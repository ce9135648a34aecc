// SPDX-License-Identifier: Apache-2.0
// Tiles on the wire: conversions between the tile module's values (tile/) and the tessera.v1
// messages, and the checks a peer runs on a tile it received. Pixels go on the wire as
// little-endian IEEE-754 float32 (the byte order is fixed by the protocol, not by the host), so a
// Python or big-endian client reads them the same way.
#pragma once

#include <cstdint>
#include <string>

#include "tessera/v1/common.pb.h"
#include "tile/tile_result.h"

namespace tessera::farm {

void to_proto(const TileRect& r, tessera::v1::TileRect* out);
TileRect from_proto(const tessera::v1::TileRect& r);

// Pixels as float32, bit for bit; the variance as bfloat16 (variance_bf16); per-pixel sample
// counts only when they differ (else uniform_spp); a frame target's block statistics
// (block_stats) when the tile has them.
void encode_tile(const TileResult& tile, tessera::v1::TileData* out);
// Checks sizes (rgb = 3*w*h floats; variance = w*h float32 or, in variance_bf16, w*h bfloat16;
// spp = w*h uint32 or none) and decodes (a uniform_spp fills spp). Returns an empty string
// on success, else what is wrong (the caller turns it into INVALID_ARGUMENT or a log line).
std::string decode_tile(const tessera::v1::TileData& in, TileResult* out);
// Block statistics on the wire (TileData.block_stats): 52 bytes a block, little-endian, every
// double and float bit for bit (the coordinator's plan must be the one `tessera render` makes).
// The rate is not carried (the planner sets it). decode returns "" or what is wrong.
std::string encode_block_stats(const std::vector<BlockStat>& blocks);
std::string decode_block_stats(const std::string& bytes, std::vector<BlockStat>* blocks);

// Only the size checks of decode_tile, without copying the pixels (the coordinator forwards the
// bytes untouched).
std::string check_tile(const tessera::v1::TileData& in, int expected_width, int expected_height);

// decode_tile, plus: the rectangle lies inside a width x height image (checked without integer
// overflow: the client must not trust a rectangle it received over the network).
std::string decode_tile_in_image(const tessera::v1::TileData& in, int width, int height, TileResult* out);

// The most rays of one kind a tile may report: far above any render (2^40 is a million samples
// a pixel of a 1024x1024 tile), far below what would overflow the farm's 64-bit sums.
inline constexpr uint64_t kMaxRaysPerTile = uint64_t(1) << 40;

// What the coordinator checks of a worker's result before it accepts it, without decoding: the
// sizes and position are those of the tile it leased (`expected`), every colour value is finite
// and every variance finite and >= 0 (a NaN would poison every later average of the frame, a
// negative variance the error report), the render time is finite and >= 0 and the ray counts
// are at most kMaxRaysPerTile (nonfinite_samples at most the camera rays). "" or what is wrong,
// naming the pixel in image coordinates.
std::string validate_tile(const tessera::v1::TileData& in, const TileRect& expected);

// The tile as the coordinator stores and forwards it: only the fields TileData defines, the bytes
// moved out of `in`. Unknown fields (in it and in its rectangle and ray counts) are dropped, so a
// peer cannot make a stored or forwarded tile larger than its pixels and identity.
tessera::v1::TileData known_fields_only(tessera::v1::TileData&& in);

}  // namespace tessera::farm

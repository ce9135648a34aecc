// Conversions between the renderer's plain structs and the tessera.v1 wire messages. Pixels go
// on the wire as little-endian IEEE-754 float32 (the byte order is fixed by the protocol, not by
// the host), so a Python or big-endian client reads them the same way.
#pragma once

#include <string>

#include "render/tile.h"
#include "scene/scene_parser.h"
#include "tessera/v1/common.pb.h"

namespace tessera::farm {

void encode_tile(const TileResult& tile, tessera::v1::TileData* out);
// Checks sizes (rgb = 3*w*h floats, variance = w*h floats) and decodes. Returns an empty string
// on success, else what is wrong (the caller turns it into INVALID_ARGUMENT or a log line).
std::string decode_tile(const tessera::v1::TileData& in, TileResult* out);
// Only the size checks of decode_tile, without copying the pixels (the coordinator forwards the
// bytes untouched).
std::string check_tile(const tessera::v1::TileData& in, int expected_width, int expected_height);

// decode_tile, plus: the rectangle lies inside a width x height image (checked without integer
// overflow: the client must not trust a rectangle it received over the network).
std::string decode_tile_in_image(const tessera::v1::TileData& in, int width, int height, TileResult* out);

void to_proto(const ImageOverrides& o, tessera::v1::ImageOverrides* out);
// Throws SceneError naming the field for an unknown sampler name.
ImageOverrides from_proto(const tessera::v1::ImageOverrides& o);
// The glTF reading options travel in the same message (gltf_* fields); only non-defaults are set.
void to_proto(const GltfOptions& o, tessera::v1::ImageOverrides* out);
// Throws SceneError naming the field and its range (gltf_scene_index >= 0, gltf_fps in (0, 1000]).
GltfOptions gltf_options_from_proto(const tessera::v1::ImageOverrides& o);

}  // namespace tessera::farm

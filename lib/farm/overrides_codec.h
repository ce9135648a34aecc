// SPDX-License-Identifier: Apache-2.0
// A job's image overrides and glTF reading options on the wire (tessera.v1.ImageOverrides): the
// client sets only what the user overrode; the coordinator and workers read them back, refusing
// values out of range by the field's name.
#pragma once

#include "scene/scene_parser.h"
#include "tessera/v1/common.pb.h"

namespace tessera::farm {

void to_proto(const ImageOverrides& o, tessera::v1::ImageOverrides* out);
// Throws SceneError naming the field for an unknown sampler name.
ImageOverrides from_proto(const tessera::v1::ImageOverrides& o);
// The glTF reading options travel in the same message (gltf_* fields); only non-defaults are set.
void to_proto(const GltfOptions& o, tessera::v1::ImageOverrides* out);
// Throws SceneError naming the field and its range (gltf_scene_index >= 0, gltf_fps in (0, 1000]).
GltfOptions gltf_options_from_proto(const tessera::v1::ImageOverrides& o);

}  // namespace tessera::farm

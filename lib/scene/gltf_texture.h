// SPDX-License-Identifier: Apache-2.0
// glTF textures: images decoded with libpng and libjpeg (the reference decoders every distro
// keeps patched, not tinygltf's bundled stb_image), sRGB-decoded to linear light, with the
// sampler's filter and wrap modes; and KHR_texture_transform.
#pragma once

#include <tiny_gltf.h>

#include <array>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "scene/scene_error.h"

namespace tessera {

class TextureDecoder {
 public:
  // `max_pixels` bounds the pixels of every texture decoded together.
  TextureDecoder(const tinygltf::Model& model, std::string file, uint64_t max_pixels, std::vector<Texture>* out)
      : model_(model), file_(std::move(file)), budget_(max_pixels), out_(out) {}
  // Decodes textures[t], read at `where` (for messages); returns its index in *out.
  int decode(size_t t, const std::string& where);

 private:
  const tinygltf::Model& model_;
  std::string file_;
  uint64_t budget_;
  std::vector<Texture>* out_;
};

// The KHR_texture_transform of a texture reference as uv' = M (u, v, 1), row-major 2x3;
// *uv_set takes its texCoord override.
std::array<double, 6> read_texture_transform(const tinygltf::ExtensionMap& extensions, int* uv_set);

// Decodes PNG or JPEG bytes into 8-bit RGB (3 per pixel); throws SceneError("<what>") with no
// file prefix. Refuses images of more than max_pixels pixels before decoding them.
std::vector<uint8_t> decode_image_rgb8(const unsigned char* bytes, size_t size, uint64_t max_pixels, int* width,
                                       int* height);

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// tinygltf's implementation, compiled here with our own definitions (README.Debian's second
// route) rather than linked from Debian's libtinygltf.so: that library's Model layout did not
// match the header as our compiler flags saw it (heap corruption on the first load), and
// compiling it here also lets us leave out stb_image: textures are decoded by libpng/libjpeg
// (gltf_texture.cpp) and no file is written.
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>

// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf_texture.h"

#include <jpeglib.h>
#include <png.h>

#include <cmath>
#include <csetjmp>
#include <cstring>

namespace tessera {

namespace {

std::vector<uint8_t> decode_png(const unsigned char* bytes, size_t size, uint64_t max_pixels, int* w, int* h) {
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&img, bytes, size)) throw SceneError(std::string("bad PNG: ") + img.message);
  if (uint64_t(img.width) * img.height > max_pixels || img.width > 65536 || img.height > 65536) {
    png_image_free(&img);
    throw SceneError("image of " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                     " pixels exceeds the texture limit (" + std::to_string(max_pixels) + " pixels in all)");
  }
  img.format = PNG_FORMAT_RGB;  // 8-bit, sRGB-encoded as stored
  std::vector<uint8_t> out(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, out.data(), 0, nullptr)) {
    const std::string m = img.message;
    png_image_free(&img);
    throw SceneError("bad PNG: " + m);
  }
  *w = int(img.width);
  *h = int(img.height);
  return out;
}

struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

void jpeg_fail(j_common_ptr c) {
  auto* e = reinterpret_cast<JpegError*>(c->err);
  (*c->err->format_message)(c, e->message);
  std::longjmp(e->jump, 1);  // libjpeg's default handler exits the process
}

std::vector<uint8_t> decode_jpeg(const unsigned char* bytes, size_t size, uint64_t max_pixels, int* w, int* h) {
  jpeg_decompress_struct cinfo;
  JpegError err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = jpeg_fail;
  err.mgr.output_message = [](j_common_ptr) {};  // warnings: silent
  std::vector<uint8_t> out;  // declared before setjmp: no object with a destructor is skipped
  std::string limit;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    throw SceneError(limit.empty() ? std::string("bad JPEG: ") + err.message : limit);
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, bytes, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  cinfo.out_color_space = JCS_RGB;
  if (uint64_t(cinfo.image_width) * cinfo.image_height > max_pixels) {
    limit = "image of " + std::to_string(cinfo.image_width) + "x" + std::to_string(cinfo.image_height) +
            " pixels exceeds the texture limit (" + std::to_string(max_pixels) + " pixels in all)";
    std::longjmp(err.jump, 1);
  }
  jpeg_start_decompress(&cinfo);
  out.resize(size_t(cinfo.output_width) * cinfo.output_height * 3);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = out.data() + size_t(cinfo.output_scanline) * cinfo.output_width * 3;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  *w = int(cinfo.output_width);
  *h = int(cinfo.output_height);
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return out;
}

// The sRGB transfer function's inverse (IEC 61966-2-1), exact per 8-bit code.
float srgb_to_linear(uint8_t c) {
  const double x = c / 255.0;
  return float(x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4));
}

Texture::Wrap wrap_mode(int gl) {
  if (gl == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return Texture::Wrap::kClamp;
  if (gl == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return Texture::Wrap::kMirror;
  return Texture::Wrap::kRepeat;
}

}  // namespace

std::vector<uint8_t> decode_image_rgb8(const unsigned char* bytes, size_t size, uint64_t max_pixels, int* width,
                                       int* height) {
  if (size >= 8 && std::memcmp(bytes, "\x89PNG\r\n\x1a\n", 8) == 0) return decode_png(bytes, size, max_pixels, width, height);
  if (size >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) {
    return decode_jpeg(bytes, size, max_pixels, width, height);
  }
  throw SceneError("not a PNG or JPEG image");
}

int TextureDecoder::decode(size_t t, const std::string& where) {
  const tinygltf::Texture& tex = model_.textures[t];
  const std::string tpath = "textures[" + std::to_string(t) + "]";
  auto fail = [&](const std::string& p, const std::string& what) {
    throw SceneError(file_ + ": " + p + " (from " + where + "): " + what);
  };
  if (tex.source < 0 || size_t(tex.source) >= model_.images.size()) {
    fail(tpath + ".source", "image " + std::to_string(tex.source) + " does not exist");
  }
  const tinygltf::Image& image = model_.images[size_t(tex.source)];
  const std::string ipath = "images[" + std::to_string(tex.source) + "]";
  Texture out;
  out.name = image.name.empty() ? ipath : image.name;
  const unsigned char* bytes = image.image.data();
  size_t size = image.image.size();
  if (image.bufferView >= 0) {
    if (size_t(image.bufferView) >= model_.bufferViews.size()) fail(ipath + ".bufferView", "does not exist");
    const tinygltf::BufferView& bv = model_.bufferViews[size_t(image.bufferView)];
    if (bv.buffer < 0 || size_t(bv.buffer) >= model_.buffers.size()) fail(ipath + ".bufferView", "its buffer does not exist");
    const auto& buf = model_.buffers[size_t(bv.buffer)].data;
    if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset) {
      fail(ipath + ".bufferView", "bufferViews[" + std::to_string(image.bufferView) + "] lies outside its buffer");
    }
    bytes = buf.data() + bv.byteOffset;
    size = bv.byteLength;
  }
  std::vector<uint8_t> rgb;
  try {
    rgb = decode_image_rgb8(bytes, size, budget_, &out.width, &out.height);
  } catch (const SceneError& e) {
    fail(ipath, e.what());
  }
  budget_ -= uint64_t(out.width) * uint64_t(out.height);
  float lut[256];
  for (int c = 0; c < 256; ++c) lut[c] = srgb_to_linear(uint8_t(c));
  auto texels = std::make_shared<std::vector<Rgb>>(size_t(out.width) * size_t(out.height));
  for (size_t i = 0; i < texels->size(); ++i) (*texels)[i] = {lut[rgb[3 * i]], lut[rgb[3 * i + 1]], lut[rgb[3 * i + 2]]};
  out.texels = std::move(texels);
  if (tex.sampler >= 0) {
    if (size_t(tex.sampler) >= model_.samplers.size()) fail(tpath + ".sampler", "does not exist");
    const tinygltf::Sampler& s = model_.samplers[size_t(tex.sampler)];
    out.nearest = s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST;
    out.wrap_s = wrap_mode(s.wrapS);
    out.wrap_t = wrap_mode(s.wrapT);
  }
  out_->push_back(std::move(out));
  return int(out_->size() - 1);
}

std::array<double, 6> read_texture_transform(const tinygltf::ExtensionMap& extensions, int* uv_set) {
  auto it = extensions.find("KHR_texture_transform");
  if (it == extensions.end() || !it->second.IsObject()) return {1, 0, 0, 0, 1, 0};
  const tinygltf::Value& e = it->second;
  auto num = [&](const tinygltf::Value& v, double fallback) {
    return v.IsNumber() && std::isfinite(v.GetNumberAsDouble()) ? v.GetNumberAsDouble() : fallback;
  };
  double ox = 0, oy = 0, rot = 0, sx = 1, sy = 1;
  if (e.Has("offset") && e.Get("offset").IsArray() && e.Get("offset").ArrayLen() == 2) {
    ox = num(e.Get("offset").Get(0), 0);
    oy = num(e.Get("offset").Get(1), 0);
  }
  if (e.Has("rotation")) rot = num(e.Get("rotation"), 0);
  if (e.Has("scale") && e.Get("scale").IsArray() && e.Get("scale").ArrayLen() == 2) {
    sx = num(e.Get("scale").Get(0), 1);
    sy = num(e.Get("scale").Get(1), 1);
  }
  if (e.Has("texCoord") && e.Get("texCoord").IsInt()) *uv_set = e.Get("texCoord").GetNumberAsInt();
  // The extension's T * R * S, with R = [cos sin; -sin cos] (its rotation runs counter-clockwise in uv).
  const double c = std::cos(rot), s = std::sin(rot);
  return {sx * c, sy * s, ox, -sx * s, sy * c, oy};
}

}  // namespace tessera

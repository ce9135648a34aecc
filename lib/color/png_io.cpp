// SPDX-License-Identifier: Apache-2.0
#include "color/png_io.h"

#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <memory>

#include "color/color_error.h"

namespace tessera::color {

namespace {

// libpng reports errors by longjmp. The functions below that call setjmp hold no C++ objects
// with destructors (everything is allocated by their callers), so the jump skips nothing.
struct PngErrorState {
  char message[256] = {};
};

void on_png_error(png_structp png, png_const_charp msg) {
  auto* state = static_cast<PngErrorState*>(png_get_error_ptr(png));
  std::snprintf(state->message, sizeof(state->message), "%s", msg);
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

struct WriteDesc {
  int width, height, color_type, bit_depth;
  png_bytepp rows;
  const png_color* palette;
  int palette_size;
  const png_byte* trans;
  int trans_size;
};

// Writes to `f`, or appends to `sink` when it is given (in-memory PNGs).
bool write_png_raw(std::FILE* f, const WriteDesc& d, PngErrorState* err, std::string* sink = nullptr) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, err, on_png_error,
                                            on_png_warning);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  if (sink) {
    png_set_write_fn(
        png, sink,
        [](png_structp p, png_bytep data, png_size_t n) {
          static_cast<std::string*>(png_get_io_ptr(p))->append(reinterpret_cast<const char*>(data), n);
        },
        [](png_structp) {});
  } else {
    png_init_io(png, f);
  }
  png_set_IHDR(png, info, png_uint_32(d.width), png_uint_32(d.height), d.bit_depth, d.color_type,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // sRGB chunk (with the gAMA/cHRM fallbacks): the samples are sRGB-encoded.
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  if (d.palette) png_set_PLTE(png, info, d.palette, d.palette_size);
  if (d.trans && d.trans_size > 0) png_set_tRNS(png, info, d.trans, d.trans_size, nullptr);
  // Palette images are never filtered better than with filter None (libpng's own advice).
  if (d.color_type == PNG_COLOR_TYPE_PALETTE) png_set_filter(png, 0, PNG_FILTER_NONE);
  png_write_info(png, info);
  if (d.bit_depth < 8) png_set_packing(png);  // rows hold one index per byte
  png_write_image(png, d.rows);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

struct ReadResult {
  png_uint_32 width = 0, height = 0;
  int color_type = 0, bit_depth = 0;
  png_colorp palette = nullptr;
  int palette_size = 0;
  png_bytep trans = nullptr;
  int trans_size = 0;
};

// Two passes: read_png_header fills the sizes, the caller allocates rows, read_png_pixels
// fills them. Both share one png/info pair owned by the caller's PngReader.
struct PngReader {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~PngReader() { png_destroy_read_struct(&png, &info, nullptr); }
};

bool read_png_header(std::FILE* f, PngReader* r, bool expand_to_rgb8, ReadResult* out,
                     PngErrorState* err) {
  r->png = png_create_read_struct(PNG_LIBPNG_VER_STRING, err, on_png_error, on_png_warning);
  if (!r->png) return false;
  r->info = png_create_info_struct(r->png);
  if (!r->info) return false;
  if (setjmp(png_jmpbuf(r->png))) return false;
  png_init_io(r->png, f);
  png_read_info(r->png, r->info);
  int interlace = 0;
  png_get_IHDR(r->png, r->info, &out->width, &out->height, &out->bit_depth, &out->color_type,
               &interlace, nullptr, nullptr);
  if (expand_to_rgb8) {
    png_set_expand(r->png);  // palette -> RGB, low-bit gray -> 8 bit, tRNS -> alpha
    png_set_strip_16(r->png);
    png_set_strip_alpha(r->png);
    png_set_gray_to_rgb(r->png);
  } else {
    if (out->bit_depth < 8) png_set_packing(r->png);
    png_get_PLTE(r->png, r->info, &out->palette, &out->palette_size);
    png_color_16p unused = nullptr;
    if (png_get_valid(r->png, r->info, PNG_INFO_tRNS)) {
      png_get_tRNS(r->png, r->info, &out->trans, &out->trans_size, &unused);
    }
  }
  if (interlace != PNG_INTERLACE_NONE) png_set_interlace_handling(r->png);
  png_read_update_info(r->png, r->info);
  return true;
}

bool read_png_pixels(PngReader* r, png_bytepp rows) {
  if (setjmp(png_jmpbuf(r->png))) return false;
  png_read_image(r->png, rows);
  png_read_end(r->png, nullptr);
  return true;
}

std::vector<png_bytep> row_pointers(uint8_t* base, int height, size_t stride) {
  std::vector<png_bytep> rows(static_cast<size_t>(height));
  for (int y = 0; y < height; ++y) rows[size_t(y)] = base + size_t(y) * stride;
  return rows;
}

FilePtr open_or_throw(const std::string& path, const char* mode) {
  FilePtr f(std::fopen(path.c_str(), mode));
  if (!f) {
    throw ColorError(std::string("cannot ") + (mode[0] == 'w' ? "write" : "read") + " PNG " +
                     path + ": " + std::strerror(errno));
  }
  return f;
}

}  // namespace

int palette_bit_depth(int colors) {
  return colors <= 2 ? 1 : colors <= 4 ? 2 : colors <= 16 ? 4 : 8;
}

namespace {
bool write_rgb8(std::FILE* f, std::string* sink, const Rgb8Image& image, PngErrorState* err) {
  auto rows = row_pointers(const_cast<uint8_t*>(image.pixels.data()), image.height,
                           size_t(image.width) * size_t(image.channels));
  const WriteDesc d{image.width, image.height,
                    image.channels == 4 ? PNG_COLOR_TYPE_RGB_ALPHA : PNG_COLOR_TYPE_RGB,
                    8, rows.data(), nullptr, 0, nullptr, 0};
  return write_png_raw(f, d, err, sink);
}
}  // namespace

void write_png(const std::string& path, const Rgb8Image& image) {
  if (image.width <= 0 || image.height <= 0 || (image.channels != 3 && image.channels != 4) ||
      image.pixels.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels)) {
    throw ColorError("cannot write PNG " + path + ": bad image size");
  }
  FilePtr f = open_or_throw(path, "wb");
  PngErrorState err;
  const bool ok = write_rgb8(f.get(), nullptr, image, &err);
  if (std::fflush(f.get()) != 0 || !ok) {
    throw ColorError("cannot write PNG " + path + ": " + (ok ? "write failed" : err.message));
  }
}

std::string encode_png(const Rgb8Image& image) {
  if (image.width <= 0 || image.height <= 0 || (image.channels != 3 && image.channels != 4) ||
      image.pixels.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels)) {
    throw ColorError("cannot encode PNG: bad image size");
  }
  std::string out;
  PngErrorState err;
  if (!write_rgb8(nullptr, &out, image, &err)) throw ColorError(std::string("cannot encode PNG: ") + err.message);
  return out;
}

void write_png_indexed(const std::string& path, const IndexedImage& image, int bit_depth) {
  const int n = int(image.palette.size());
  if (image.width <= 0 || image.height <= 0 || n < 1 || n > 256 ||
      image.indices.size() != size_t(image.width) * size_t(image.height) ||
      image.alpha.size() > image.palette.size()) {
    throw ColorError("cannot write PNG " + path + ": bad indexed image");
  }
  for (uint8_t i : image.indices) {
    if (i >= n) throw ColorError("cannot write PNG " + path + ": index beyond the palette");
  }
  const int depth = std::max(bit_depth, palette_bit_depth(n));
  if (depth != 1 && depth != 2 && depth != 4 && depth != 8) {
    throw ColorError("cannot write PNG " + path + ": bad bit depth");
  }
  std::vector<png_color> plte(size_t(n), png_color{});
  for (int i = 0; i < n; ++i) {
    plte[size_t(i)] = {image.palette[size_t(i)].r, image.palette[size_t(i)].g,
                       image.palette[size_t(i)].b};
  }
  FilePtr f = open_or_throw(path, "wb");
  auto rows = row_pointers(const_cast<uint8_t*>(image.indices.data()), image.height,
                           size_t(image.width));
  const WriteDesc d{image.width, image.height, PNG_COLOR_TYPE_PALETTE, depth, rows.data(),
                    plte.data(), n, image.alpha.empty() ? nullptr : image.alpha.data(),
                    int(image.alpha.size())};
  PngErrorState err;
  const bool ok = write_png_raw(f.get(), d, &err);
  if (std::fflush(f.get()) != 0 || !ok) {
    throw ColorError("cannot write PNG " + path + ": " + (ok ? "write failed" : err.message));
  }
}

IndexedImage read_png_indexed(const std::string& path, int* bit_depth) {
  FilePtr f = open_or_throw(path, "rb");
  PngReader reader;
  ReadResult r;
  PngErrorState err;
  if (!read_png_header(f.get(), &reader, false, &r, &err)) {
    throw ColorError("cannot read PNG " + path + ": " + err.message);
  }
  if (r.color_type != PNG_COLOR_TYPE_PALETTE || !r.palette || r.palette_size < 1) {
    throw ColorError(path + " is not an indexed (palette) PNG; make one with "
                            "`tessera convert IN.exr OUT.png --format palette`");
  }
  if (r.width > (1u << 16) || r.height > (1u << 16)) throw ColorError(path + ": image too large");
  IndexedImage out;
  out.width = int(r.width);
  out.height = int(r.height);
  for (int i = 0; i < r.palette_size; ++i) {
    out.palette.push_back({r.palette[i].red, r.palette[i].green, r.palette[i].blue});
  }
  if (r.trans) out.alpha.assign(r.trans, r.trans + r.trans_size);
  if (bit_depth) *bit_depth = r.bit_depth;
  out.indices.resize(size_t(out.width) * size_t(out.height));
  auto rows = row_pointers(out.indices.data(), out.height, size_t(out.width));
  if (!read_png_pixels(&reader, rows.data())) {
    throw ColorError("cannot read PNG " + path + ": " + err.message);
  }
  return out;
}

Rgb8Image read_png_rgb8(const std::string& path) {
  FilePtr f = open_or_throw(path, "rb");
  PngReader reader;
  ReadResult r;
  PngErrorState err;
  if (!read_png_header(f.get(), &reader, true, &r, &err)) {
    throw ColorError("cannot read PNG " + path + ": " + err.message);
  }
  if (r.width > (1u << 16) || r.height > (1u << 16)) throw ColorError(path + ": image too large");
  Rgb8Image out;
  out.width = int(r.width);
  out.height = int(r.height);
  out.channels = 3;
  if (png_get_rowbytes(reader.png, reader.info) != size_t(out.width) * 3) {
    throw ColorError("cannot read PNG " + path + ": unexpected row layout");
  }
  out.pixels.resize(size_t(out.width) * size_t(out.height) * 3);
  auto rows = row_pointers(out.pixels.data(), out.height, size_t(out.width) * 3);
  if (!read_png_pixels(&reader, rows.data())) {
    throw ColorError("cannot read PNG " + path + ": " + err.message);
  }
  return out;
}

}  // namespace tessera::color

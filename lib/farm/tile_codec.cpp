#include "farm/tile_codec.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace tessera::farm {

namespace {

static_assert(sizeof(float) == 4);

// 32-bit words (float32 or uint32) to and from little-endian bytes.
template <typename T>
void words_to_le(const std::vector<T>& v, std::string* out) {
  static_assert(sizeof(T) == 4);
  out->resize(v.size() * 4);
  if (v.empty()) return;  // memcpy from an empty vector's null data() is undefined, even for 0 bytes
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(out->data(), v.data(), out->size());
  } else {
    for (size_t i = 0; i < v.size(); ++i) {
      uint32_t u = std::bit_cast<uint32_t>(v[i]);
      for (int b = 0; b < 4; ++b) (*out)[i * 4 + size_t(b)] = char((u >> (8 * b)) & 0xff);
    }
  }
}

template <typename T>
void le_to_words(const std::string& s, std::vector<T>* v) {
  static_assert(sizeof(T) == 4);
  v->resize(s.size() / 4);
  if (v->empty()) return;  // as above: no memcpy to a null data()
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(v->data(), s.data(), v->size() * 4);
  } else {
    for (size_t i = 0; i < v->size(); ++i) {
      uint32_t u = 0;
      for (int b = 0; b < 4; ++b) u |= uint32_t(uint8_t(s[i * 4 + size_t(b)])) << (8 * b);
      (*v)[i] = std::bit_cast<T>(u);
    }
  }
}

// The index of the first float32 (little-endian) in `bytes` that is NaN or infinite, or -1.
int64_t first_nonfinite(const std::string& bytes) {
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  for (size_t i = 0; i + 4 <= bytes.size(); i += 4) {
    const uint32_t bits = uint32_t(p[i]) | uint32_t(p[i + 1]) << 8 | uint32_t(p[i + 2]) << 16 | uint32_t(p[i + 3]) << 24;
    if ((bits & 0x7f800000u) == 0x7f800000u) return int64_t(i / 4);
  }
  return -1;
}

float le_float_at(const std::string& bytes, int64_t index) {
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data()) + index * 4;
  return std::bit_cast<float>(uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24);
}

}  // namespace

void to_proto(const TileRect& r, tessera::v1::TileRect* out) {
  out->set_x0(r.x0);
  out->set_y0(r.y0);
  out->set_width(r.width);
  out->set_height(r.height);
}

TileRect from_proto(const tessera::v1::TileRect& r) { return {r.x0(), r.y0(), r.width(), r.height()}; }

void encode_tile(const TileResult& tile, tessera::v1::TileData* out) {
  to_proto(tile.rect, out->mutable_rect());
  words_to_le(tile.rgb, out->mutable_rgb());
  words_to_le(tile.variance, out->mutable_variance());
  words_to_le(tile.spp, out->mutable_spp());
  auto* rays = out->mutable_rays();
  rays->set_camera(tile.rays.camera);
  rays->set_shadow(tile.rays.shadow);
  rays->set_secondary(tile.rays.secondary);
  rays->set_nonfinite_samples(tile.rays.nonfinite_samples);
  out->set_seconds(tile.seconds);
}

std::string check_tile(const tessera::v1::TileData& in, int w, int h) {
  const auto& r = in.rect();
  if (w <= 0 || h <= 0) return "tile has an empty rectangle";
  if (r.width() != w || r.height() != h) {
    return "tile is " + std::to_string(r.width()) + "x" + std::to_string(r.height()) + ", expected " +
           std::to_string(w) + "x" + std::to_string(h);
  }
  const size_t px = size_t(w) * size_t(h);
  if (in.rgb().size() != px * 12) {
    return "tile rgb has " + std::to_string(in.rgb().size()) + " bytes, expected " + std::to_string(px * 12);
  }
  if (in.variance().size() != px * 4) {
    return "tile variance has " + std::to_string(in.variance().size()) + " bytes, expected " + std::to_string(px * 4);
  }
  if (!in.spp().empty() && in.spp().size() != px * 4) {
    return "tile spp has " + std::to_string(in.spp().size()) + " bytes, expected " + std::to_string(px * 4) + " or none";
  }
  return {};
}

std::string decode_tile(const tessera::v1::TileData& in, TileResult* out) {
  if (in.rect().width() <= 0 || in.rect().height() <= 0) return "tile has an empty rectangle";
  std::string err = check_tile(in, in.rect().width(), in.rect().height());
  if (!err.empty()) return err;
  out->rect = from_proto(in.rect());
  le_to_words(in.rgb(), &out->rgb);
  le_to_words(in.variance(), &out->variance);
  le_to_words(in.spp(), &out->spp);
  out->rays.camera = in.rays().camera();
  out->rays.shadow = in.rays().shadow();
  out->rays.secondary = in.rays().secondary();
  out->rays.nonfinite_samples = in.rays().nonfinite_samples();
  out->seconds = in.seconds();
  return {};
}

std::string decode_tile_in_image(const tessera::v1::TileData& in, int width, int height, TileResult* out) {
  const auto& r = in.rect();
  // 64-bit sums: x0 + width cannot overflow, whatever the peer sent.
  if (r.x0() < 0 || r.y0() < 0 || int64_t(r.x0()) + r.width() > width || int64_t(r.y0()) + r.height() > height) {
    return "tile rectangle (" + std::to_string(r.x0()) + ", " + std::to_string(r.y0()) + ") " +
           std::to_string(r.width()) + "x" + std::to_string(r.height()) + " is outside the " + std::to_string(width) +
           "x" + std::to_string(height) + " image";
  }
  return decode_tile(in, out);
}

std::string validate_tile(const tessera::v1::TileData& in, const TileRect& expected) {
  std::string err = check_tile(in, expected.width, expected.height);
  if (!err.empty()) return err;
  if (in.rect().x0() != expected.x0 || in.rect().y0() != expected.y0) {
    return "tile at (" + std::to_string(in.rect().x0()) + ", " + std::to_string(in.rect().y0()) + "), expected (" +
           std::to_string(expected.x0) + ", " + std::to_string(expected.y0) + ")";
  }
  const auto pixel = [&](int64_t p) {
    return "(" + std::to_string(expected.x0 + p % expected.width) + ", " + std::to_string(expected.y0 + p / expected.width) +
           ")";
  };
  if (const int64_t i = first_nonfinite(in.rgb()); i >= 0) {
    return "pixel " + pixel(i / 3) + " channel " + std::to_string(i % 3) + " is " +
           (std::isnan(le_float_at(in.rgb(), i)) ? "NaN" : "infinite");
  }
  if (const int64_t j = first_nonfinite(in.variance()); j >= 0) return "variance of pixel " + pixel(j) + " is not finite";
  return {};
}

}  // namespace tessera::farm

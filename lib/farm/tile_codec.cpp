// SPDX-License-Identifier: Apache-2.0
#include "farm/tile_codec.h"

#include "tile/bfloat16.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <utility>

namespace tessera::farm {

namespace {

static_assert(sizeof(float) == 4);

// The little-endian 32- and 16-bit words at `p`: every read of the wire's bytes uses these.
uint32_t le_u32_at(const char* p) {
  uint32_t u;
  std::memcpy(&u, p, 4);
  if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap32(u);
  return u;
}

uint16_t le_u16_at(const char* p) { return uint16_t(uint8_t(p[0]) | uint8_t(p[1]) << 8); }

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
    for (size_t i = 0; i < v->size(); ++i) (*v)[i] = std::bit_cast<T>(le_u32_at(s.data() + 4 * i));
  }
}

bool nonfinite_f32(uint32_t u) { return (u & 0x7f800000u) == 0x7f800000u; }
// NaN, infinite or below zero (-0 is zero): not a variance.
bool bad_variance_f32(uint32_t u) { return nonfinite_f32(u) || u > 0x80000000u; }

// The index of the first word (little-endian) in `bytes` for which `bad` holds, or -1. The
// coordinator runs this over every tile it accepts, so it must run at memory speed: whole blocks
// of 64 words are tested without an early exit, a loop of constant count that GCC vectorizes at
// -O2 (a loop with a branch per value, or one whose count the compiler cannot see, stays scalar:
// 2.8 us for a 32 px tile's rgb against 0.8 us). Only the block with a bad value, and the tail,
// are searched one by one.
template <class Word>
Word from_le(Word w) {
  if constexpr (std::endian::native == std::endian::big) {
    if constexpr (sizeof(Word) == 4) return Word(__builtin_bswap32(w));
    if constexpr (sizeof(Word) == 2) return Word(__builtin_bswap16(w));
  }
  return w;
}
template <class Word, bool (*bad)(Word)>
int64_t first_word(const std::string& bytes) {
  constexpr size_t kBlock = 64;
  const size_t n = bytes.size() / sizeof(Word);
  const char* p = bytes.data();
  size_t base = 0;
  for (; base + kBlock <= n; base += kBlock) {
    Word w[kBlock];
    std::memcpy(w, p + sizeof(Word) * base, sizeof w);
    Word any = 0;
    for (size_t i = 0; i < kBlock; ++i) any |= Word(bad(from_le(w[i])));
    if (any) break;
  }
  for (size_t i = base; i < n; ++i) {
    Word w;
    std::memcpy(&w, p + sizeof(Word) * i, sizeof w);
    if (bad(from_le(w))) return int64_t(i);
  }
  return -1;
}
template <bool (*bad)(uint32_t)>
int64_t first_f32(const std::string& bytes) {
  return first_word<uint32_t, bad>(bytes);
}
int64_t first_nonfinite(const std::string& bytes) { return first_f32<nonfinite_f32>(bytes); }

void floats_to_bf16_le(const std::vector<float>& v, std::string* out) {
  out->resize(v.size() * 2);
  for (size_t i = 0; i < v.size(); ++i) {
    const uint16_t h = to_bfloat16(v[i]);
    (*out)[2 * i] = char(h & 0xff);
    (*out)[2 * i + 1] = char(h >> 8);
  }
}

void bf16_le_to_floats(const std::string& s, std::vector<float>* v) {
  v->resize(s.size() / 2);
  for (size_t i = 0; i < v->size(); ++i) (*v)[i] = from_bfloat16(le_u16_at(s.data() + 2 * i));
}

// NaN, infinite or negative as a bfloat16 (the top half of a float32): not a variance.
bool bad_variance_bf16(uint16_t h) { return bad_variance_f32(uint32_t(h) << 16); }
// The index of the first bfloat16 (little-endian) in `bytes` that is not a variance, or -1.
int64_t first_bad_variance_bf16(const std::string& bytes) { return first_word<uint16_t, bad_variance_bf16>(bytes); }

// Why a variance value is refused.
std::string variance_problem(float v) {
  if (std::isnan(v)) return "is NaN";
  if (std::isinf(v)) return "is infinite";
  return "is negative (" + std::to_string(v) + ")";
}

float le_float_at(const std::string& bytes, int64_t index) {
  return std::bit_cast<float>(le_u32_at(bytes.data() + 4 * index));
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
  out->clear_variance();
  floats_to_bf16_le(tile.variance, out->mutable_variance_bf16());
  // A fixed-spp tile (and an adaptive one whose every pixel stopped at the same count) says the
  // count once instead of 4 bytes a pixel.
  const bool uniform = !tile.spp.empty() && std::all_of(tile.spp.begin(), tile.spp.end(),
                                                        [&](uint32_t n) { return n == tile.spp.front(); });
  if (uniform) {
    out->clear_spp();
    out->set_uniform_spp(tile.spp.front());
  } else {
    words_to_le(tile.spp, out->mutable_spp());
    out->set_uniform_spp(0);
  }
  auto* rays = out->mutable_rays();
  rays->set_camera(tile.rays.camera);
  rays->set_shadow(tile.rays.shadow);
  rays->set_secondary(tile.rays.secondary);
  rays->set_nonfinite_samples(tile.rays.nonfinite_samples);
  out->set_seconds(tile.seconds);
  if (!tile.blocks.empty()) out->set_block_stats(encode_block_stats(tile.blocks));
}

namespace {

constexpr size_t kBlockStatBytes = 52;

// Little-endian unsigned integers of any width, whatever the host.
template <class U>
void put_le(U v, char* p) {
  for (size_t k = 0; k < sizeof(U); ++k) p[k] = char((v >> (8 * k)) & 0xff);
}
template <class U>
U le_at(const char* p) {
  U v = 0;
  for (size_t k = 0; k < sizeof(U); ++k) v |= U(uint8_t(p[k])) << (8 * k);
  return v;
}

}  // namespace

std::string encode_block_stats(const std::vector<BlockStat>& blocks) {
  std::string out(blocks.size() * kBlockStatBytes, '\0');
  for (size_t i = 0; i < blocks.size(); ++i) {
    char* p = out.data() + i * kBlockStatBytes;
    const BlockStat& b = blocks[i];
    put_le<uint64_t>(uint64_t(b.block), p);
    put_le<uint64_t>(uint64_t(b.spp) | uint64_t(b.pixels) << 32, p + 8);
    put_le<uint64_t>(std::bit_cast<uint64_t>(b.mse), p + 16);
    put_le<uint64_t>(std::bit_cast<uint64_t>(b.shape_mse), p + 24);
    put_le<uint64_t>(std::bit_cast<uint64_t>(b.cost), p + 32);
    for (int c = 0; c < 3; ++c) put_le<uint32_t>(std::bit_cast<uint32_t>(b.mean[size_t(c)]), p + 40 + 4 * c);
  }
  return out;
}

std::string decode_block_stats(const std::string& bytes, std::vector<BlockStat>* blocks) {
  if (bytes.size() % kBlockStatBytes != 0) {
    return "block_stats has " + std::to_string(bytes.size()) + " bytes, not a multiple of " +
           std::to_string(kBlockStatBytes);
  }
  blocks->assign(bytes.size() / kBlockStatBytes, BlockStat{});
  for (size_t i = 0; i < blocks->size(); ++i) {
    const char* p = bytes.data() + i * kBlockStatBytes;
    BlockStat& b = (*blocks)[i];
    b.block = int64_t(le_at<uint64_t>(p));
    const uint64_t counts = le_at<uint64_t>(p + 8);
    b.spp = uint32_t(counts & 0xffffffffu);
    b.pixels = uint32_t(counts >> 32);
    b.mse = std::bit_cast<double>(le_at<uint64_t>(p + 16));
    b.shape_mse = std::bit_cast<double>(le_at<uint64_t>(p + 24));
    b.cost = std::bit_cast<double>(le_at<uint64_t>(p + 32));
    for (int c = 0; c < 3; ++c) b.mean[size_t(c)] = std::bit_cast<float>(le_at<uint32_t>(p + 40 + 4 * c));
    const std::string which = "block_stats[" + std::to_string(i) + "] (block " + std::to_string(b.block) + ")";
    if (b.block < 0) return which + ": negative block index";
    if (b.spp == 0 || b.pixels == 0) return which + ": no samples or no pixels";
    for (const auto& [name, v] : {std::pair{"mse", b.mse}, std::pair{"shape_mse", b.shape_mse}}) {
      if (!std::isfinite(v) || v < 0) return which + ": " + name + " " + std::to_string(v) + " is not finite and >= 0";
    }
    if (b.shape_mse < b.mse) return which + ": shape_mse is below mse";
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(b.mean[size_t(c)])) return which + ": mean " + "RGB"[c] + " is not finite";
    }
    if (!std::isfinite(b.cost) || !(b.cost >= 1)) {
      return which + ": rays per sample " + std::to_string(b.cost) + " is not finite and >= 1";
    }
  }
  return {};
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
  if (!in.variance().empty() && !in.variance_bf16().empty()) return "tile has both variance and variance_bf16";
  if (in.variance().empty() && in.variance_bf16().empty()) {
    return "tile has no variance (variance_bf16: " + std::to_string(px * 2) + " bytes, or variance: " +
           std::to_string(px * 4) + ")";
  }
  if (!in.variance_bf16().empty()) {
    if (in.variance_bf16().size() != px * 2) {
      return "tile variance_bf16 has " + std::to_string(in.variance_bf16().size()) + " bytes, expected " +
             std::to_string(px * 2);
    }
  } else if (in.variance().size() != px * 4) {
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
  if (in.variance_bf16().empty()) {
    le_to_words(in.variance(), &out->variance);
  } else {
    bf16_le_to_floats(in.variance_bf16(), &out->variance);
  }
  if (in.spp().empty() && in.uniform_spp() > 0) {
    out->spp.assign(out->variance.size(), in.uniform_spp());
  } else {
    le_to_words(in.spp(), &out->spp);
  }
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
  if (const int64_t j = first_f32<bad_variance_f32>(in.variance()); j >= 0) {
    return "variance of pixel " + pixel(j) + " " + variance_problem(le_float_at(in.variance(), j));
  }
  if (const int64_t j = first_bad_variance_bf16(in.variance_bf16()); j >= 0) {
    const float v = from_bfloat16(le_u16_at(in.variance_bf16().data() + 2 * j));
    return "variance of pixel " + pixel(j) + " " + variance_problem(v);
  }
  // The statistics a tile carries feed reports and metrics: a NaN time or an absurd count would
  // poison every sum after it.
  if (!std::isfinite(in.seconds()) || in.seconds() < 0) {
    return "render time " + std::to_string(in.seconds()) + " s is not a finite duration >= 0";
  }
  const auto& rays = in.rays();
  for (const auto& [name, count] : {std::pair{"camera", rays.camera()}, std::pair{"shadow", rays.shadow()},
                                    std::pair{"secondary", rays.secondary()}}) {
    if (count > kMaxRaysPerTile) {
      return std::string(name) + " ray count " + std::to_string(count) + " is above " +
             std::to_string(kMaxRaysPerTile) + " per tile";
    }
  }
  if (rays.nonfinite_samples() > rays.camera()) {
    return "nonfinite_samples " + std::to_string(rays.nonfinite_samples()) + " is above the camera ray count " +
           std::to_string(rays.camera());
  }
  return {};
}

tessera::v1::TileData known_fields_only(tessera::v1::TileData&& in) {
  // Field by field, not CopyFrom: CopyFrom keeps unknown fields. codec test
  // KnownFieldsOnlyKeepsEveryFieldTileDataDefines fails when a field is added here and not below.
  tessera::v1::TileData out;
  out.set_job_id(std::move(*in.mutable_job_id()));
  out.set_frame(in.frame());
  out.set_tile_index(in.tile_index());
  if (in.has_rect()) to_proto(from_proto(in.rect()), out.mutable_rect());
  out.set_rgb(std::move(*in.mutable_rgb()));
  out.set_variance(std::move(*in.mutable_variance()));
  if (in.has_rays()) {
    auto* r = out.mutable_rays();
    r->set_camera(in.rays().camera());
    r->set_shadow(in.rays().shadow());
    r->set_secondary(in.rays().secondary());
    r->set_nonfinite_samples(in.rays().nonfinite_samples());
  }
  out.set_seconds(in.seconds());
  out.set_worker(std::move(*in.mutable_worker()));
  out.set_spp(std::move(*in.mutable_spp()));
  out.set_variance_bf16(std::move(*in.mutable_variance_bf16()));
  out.set_uniform_spp(in.uniform_spp());
  out.set_block_stats(std::move(*in.mutable_block_stats()));
  return out;
}

}  // namespace tessera::farm

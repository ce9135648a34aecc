#include "farm/codec.h"

#include <bit>
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

}  // namespace

void encode_tile(const TileResult& tile, tessera::v1::TileData* out) {
  auto* r = out->mutable_rect();
  r->set_x0(tile.rect.x0);
  r->set_y0(tile.rect.y0);
  r->set_width(tile.rect.width);
  r->set_height(tile.rect.height);
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
  out->rect = {in.rect().x0(), in.rect().y0(), in.rect().width(), in.rect().height()};
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

void to_proto(const ImageOverrides& o, tessera::v1::ImageOverrides* out) {
  if (o.width) out->set_width(*o.width);
  if (o.height) out->set_height(*o.height);
  if (o.spp) out->set_spp(*o.spp);
  if (o.max_depth) out->set_max_depth(*o.max_depth);
  if (o.seed) out->set_seed(*o.seed);
  if (o.sampler) out->set_sampler(sampler_name(*o.sampler));
  if (o.target_rmse) out->set_target_rmse(*o.target_rmse);
  if (o.min_spp) out->set_min_spp(*o.min_spp);
  if (o.max_spp) out->set_max_spp(*o.max_spp);
}

ImageOverrides from_proto(const tessera::v1::ImageOverrides& o) {
  ImageOverrides out;
  if (o.has_width()) out.width = o.width();
  if (o.has_height()) out.height = o.height();
  if (o.has_spp()) out.spp = o.spp();
  if (o.has_max_depth()) out.max_depth = o.max_depth();
  if (o.has_seed()) out.seed = o.seed();
  if (o.has_sampler()) {
    out.sampler = sampler_from_name(o.sampler());
    if (!out.sampler) {
      throw SceneError(std::string("overrides.sampler: must be one of ") + sampler_names() + ", got '" +
                       o.sampler() + "'");
    }
  }
  if (o.has_target_rmse()) out.target_rmse = o.target_rmse();
  if (o.has_min_spp()) out.min_spp = o.min_spp();
  if (o.has_max_spp()) out.max_spp = o.max_spp();
  return out;
}

void to_proto(const GltfOptions& o, tessera::v1::ImageOverrides* out) {
  if (!o.camera.empty()) out->set_gltf_camera(o.camera);
  if (o.scene_index != GltfOptions{}.scene_index) out->set_gltf_scene_index(o.scene_index);
  if (o.fps != GltfOptions::kDefaultFps) out->set_gltf_fps(o.fps);
}

GltfOptions gltf_options_from_proto(const tessera::v1::ImageOverrides& o) {
  GltfOptions out;
  if (o.has_gltf_camera()) out.camera = o.gltf_camera();
  if (o.has_gltf_scene_index()) {
    if (o.gltf_scene_index() < 0) {
      throw SceneError("overrides.gltf_scene_index: must be >= 0, got " + std::to_string(o.gltf_scene_index()));
    }
    out.scene_index = o.gltf_scene_index();
  }
  if (o.has_gltf_fps()) {
    if (!(o.gltf_fps() > 0 && o.gltf_fps() <= GltfOptions::kMaxFps)) {
      throw SceneError("overrides.gltf_fps: must be in (0, " + std::to_string(int(GltfOptions::kMaxFps)) + "], got " +
                       std::to_string(o.gltf_fps()));
    }
    out.fps = o.gltf_fps();
  }
  return out;
}

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
#include "farm/overrides_codec.h"

namespace tessera::farm {

void to_proto(const ImageOverrides& o, tessera::v1::ImageOverrides* out) {
  if (o.width) out->set_width(*o.width);
  if (o.height) out->set_height(*o.height);
  if (o.spp) out->set_spp(*o.spp);
  if (o.max_depth) out->set_max_depth(*o.max_depth);
  if (o.seed) out->set_seed(*o.seed);
  if (o.sampler) out->set_sampler(sampler_name(*o.sampler));
  if (o.target_rmse) out->set_target_rmse(*o.target_rmse);
  if (o.block_rmse) out->set_block_rmse(*o.block_rmse);
  if (o.min_spp) out->set_min_spp(*o.min_spp);
  if (o.max_spp) out->set_max_spp(*o.max_spp);
  if (o.roulette_weight) out->set_roulette_weight(*o.roulette_weight);
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
  if (o.has_block_rmse()) out.block_rmse = o.block_rmse();
  if (o.has_min_spp()) out.min_spp = o.min_spp();
  if (o.has_max_spp()) out.max_spp = o.max_spp();
  if (o.has_roulette_weight()) out.roulette_weight = o.roulette_weight();
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

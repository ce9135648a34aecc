// SPDX-License-Identifier: Apache-2.0
#include "frame_passes.h"

#include <climits>

#include "farm/overrides_codec.h"
#include "farm/tile_codec.h"
#include "tessera/v1/common.pb.h"
#include "tile/tile_grid.h"

namespace tessera::server {

std::optional<ImageSettings> FramePasses::settings_of(const JobSpec& spec) {
  v1::ImageOverrides o;
  if (!o.ParseFromString(spec.overrides) || !o.has_target_rmse()) return std::nullopt;
  ImageSettings s;
  s.width = spec.width;
  s.height = spec.height;
  s.target_rmse = o.target_rmse();
  if (o.has_min_spp()) s.min_spp = o.min_spp();
  if (o.has_max_spp()) s.max_spp = o.max_spp();
  if (o.has_sampler()) s.sampler = sampler_from_name(o.sampler()).value_or(s.sampler);
  return s;
}

PassDecision FramePasses::plan(const JobSpec& spec, const JobId& job, int frame, int passes_done,
                               const std::vector<const TileOutput*>& outputs) {
  PassDecision d;
  const auto img = settings_of(spec);
  if (!img) {
    d.error = "the job's settings have no frame target to plan passes for";
    return d;
  }
  const BlockGrid blocks(spec.width, spec.height);
  const TileGrid tiles(spec.width, spec.height, spec.tile_size);
  const auto key = std::make_pair(job, frame);
  FrameState& st = frames_[key];
  if (st.stats.empty()) {
    st.stats.resize(size_t(blocks.count()));
    const std::vector<uint32_t> pilot(size_t(blocks.count()), uint32_t(img->first_spp()));
    st.rendered_with.resize(size_t(tiles.count()));
    for (int t = 0; t < tiles.count(); ++t) st.rendered_with[size_t(t)] = tile_plan(blocks, tiles.rect(t), pilot);
  }
  const auto fail = [&](std::string why) {
    frames_.erase(key);
    d.error = std::move(why);
    return d;
  };
  // Every tile's statistics: the blocks whose first pixel it holds, each at the count its plan
  // gave (a worker that did something else is not planned from).
  std::vector<BlockStat> reported;
  for (int t = 0; t < tiles.count() && t < int(outputs.size()); ++t) {
    const TileRect rect = tiles.rect(t);
    v1::TileData tile;
    if (!outputs[size_t(t)]->payload || !tile.ParseFromString(*outputs[size_t(t)]->payload)) {
      return fail("tile " + std::to_string(t) + " cannot be read back");
    }
    if (std::string err = farm::decode_block_stats(tile.block_stats(), &reported); !err.empty()) {
      return fail("tile " + std::to_string(t) + " from worker '" + tile.worker() + "': " + err);
    }
    if (int(reported.size()) != blocks.origins_in(rect)) {
      return fail("tile " + std::to_string(t) + " from worker '" + tile.worker() + "' carries " +
                  std::to_string(reported.size()) + " block statistics, expected " +
                  std::to_string(blocks.origins_in(rect)) + " (a worker that does not render frame targets?)");
    }
    const BlockGrid::Range r = blocks.meeting(rect);
    for (BlockStat& b : reported) {
      const int col = int(b.block % blocks.cols), row = int(b.block / blocks.cols);
      if (b.block >= blocks.count() || col * kAllocationBlock < rect.x0 || row * kAllocationBlock < rect.y0 ||
          col >= r.col1 || row >= r.row1) {
        return fail("tile " + std::to_string(t) + " reports block " + std::to_string(b.block) + ", which it does not hold");
      }
      const uint32_t planned = st.rendered_with[size_t(t)][size_t((row - r.row0) * (r.col1 - r.col0) + (col - r.col0))];
      const int w = std::min(kAllocationBlock, spec.width - col * kAllocationBlock);
      const int h = std::min(kAllocationBlock, spec.height - row * kAllocationBlock);
      if (b.spp != planned || b.pixels != uint32_t(w * h)) {
        return fail("tile " + std::to_string(t) + " reports block " + std::to_string(b.block) + " at " +
                    std::to_string(b.spp) + " samples of " + std::to_string(b.pixels) + " pixels, planned " +
                    std::to_string(planned) + " of " + std::to_string(w * h));
      }
      b.rate = first_rate(img->sampler);
      st.stats[size_t(b.block)] = updated_stat(st.stats[size_t(b.block)], b);
    }
  }
  const auto counts = next_pass_counts(st.stats, blocks, *img, passes_done);
  if (!counts) {
    frames_.erase(key);
    return d;  // final
  }
  d.final = false;
  d.plans.resize(size_t(tiles.count()));
  for (int t = 0; t < tiles.count(); ++t) {
    SamplePlan p = tile_plan(blocks, tiles.rect(t), *counts);
    if (p == st.rendered_with[size_t(t)]) continue;  // none of its blocks takes more samples
    d.plans[size_t(t)] = encode_plan(p);
    st.rendered_with[size_t(t)] = std::move(p);
  }
  return d;
}

void FramePasses::forget(const JobId& job) {
  for (auto it = frames_.lower_bound({job, INT32_MIN}); it != frames_.end() && it->first.first == job;) {
    it = frames_.erase(it);
  }
}

}  // namespace tessera::server

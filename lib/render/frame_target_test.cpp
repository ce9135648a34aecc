// SPDX-License-Identifier: Apache-2.0
// Rendering to a frame's target error: the frame meets the target without paying for far less
// error, its estimate is honest against a high-spp reference, and every pixel is a pure function
// of (scene, frame, settings).
#include "render/frame_target.h"
#include "render/render_scene_internal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "render/test_scenes.h"
#include "scene/scene_parser.h"
#include "tile/tile_grid.h"

namespace tessera {
namespace {

Scene target_scene(int w, int h, double target, int min_spp, int max_spp) {
  Scene s = parse_scene(test::whitted_like(w, h, 16), "test.json");
  s.image.target_rmse = target;
  s.image.min_spp = min_spp;
  s.image.max_spp = max_spp;
  return s;
}

double rmse(const ImageRGB& a, const ImageRGB& b) {
  double se = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i) se += (double(a.rgb[i]) - double(b.rgb[i])) * (double(a.rgb[i]) - double(b.rgb[i]));
  return std::sqrt(se / double(a.rgb.size()));
}

TEST(FrameTarget, TheFrameMeetsItsTargetAndItsEstimateIsHonest) {
  const double target = 0.004;
  RenderScene rs(target_scene(64, 40, target, 8, 1024), 0);
  const FrameResult r = render_frame(rs, 32, 2);
  const SampleSummary s = r.summary();
  EXPECT_TRUE(s.target_reached);
  EXPECT_LE(s.estimated_rmse, target);
  // Not far below it either: the frame gets the error asked for, not a fraction of it.
  EXPECT_GT(s.estimated_rmse, 0.7 * target);
  EXPECT_EQ(s.min_spp, 8u);
  EXPECT_GT(s.max_spp, 4 * s.min_spp) << "the samples went somewhere in particular";
  // Honest: against an independent reference (another seed, uniform 1024 spp).
  Scene ref_scene = parse_scene(test::whitted_like(64, 40, 1024), "test.json");
  ref_scene.image.seed = 99;
  RenderScene ref_rs(ref_scene, 0);
  const double measured = rmse(r.image, render_frame(ref_rs, 32, 2).image);
  std::printf("target %.4g: estimated %.4g, measured %.4g, mean spp %.1f\n", target, s.estimated_rmse, measured,
              s.mean_spp);
  EXPECT_GT(s.estimated_rmse / measured, 0.7);
  EXPECT_LT(s.estimated_rmse / measured, 1.4);
}

TEST(FrameTarget, BitIdenticalForAnyThreadCountAndRepetition) {
  RenderScene rs(target_scene(75, 53, 0.006, 8, 256), 0);  // odd sizes: blocks clipped at the edges
  const FrameResult ref = render_frame(rs, 32, 1);
  for (int threads : {2, 3}) {
    RenderScene again(target_scene(75, 53, 0.006, 8, 256), 0);  // another Embree scene, as on another machine
    const FrameResult r = render_frame(again, 16, threads);
    ASSERT_EQ(r.image.rgb, ref.image.rgb) << threads;
    ASSERT_EQ(r.variance, ref.variance) << threads;
    ASSERT_EQ(r.spp, ref.spp) << threads;
  }
}

TEST(FrameTarget, APixelWithNSamplesEqualsTheUniformNSppRender) {
  RenderScene rs(target_scene(48, 32, 0.005, 8, 128), 0);
  const FrameResult a = render_frame(rs, 32, 2);
  std::map<uint32_t, FrameResult> uniform;
  for (size_t i = 0; i < a.spp.size(); ++i) {
    const uint32_t n = a.spp[i];
    if (!uniform.count(n)) {
      RenderScene u(parse_scene(test::whitted_like(48, 32, int(n)), "test.json"), 0);
      uniform.emplace(n, render_frame(u, 32, 2));
    }
    const FrameResult& u = uniform.at(n);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(a.image.rgb[3 * i + size_t(c)], u.image.rgb[3 * i + size_t(c)]) << i;
    ASSERT_EQ(a.variance[i], u.variance[i]) << i;
  }
  EXPECT_GE(uniform.size(), 3u);  // several counts were compared
}

TEST(FrameTarget, AnUnreachableTargetStopsAtMaxSppAndSaysSo) {
  RenderScene rs(target_scene(40, 24, 1e-5, 8, 24), 0);
  const FrameResult r = render_frame(rs, 32, 2);
  const SampleSummary s = r.summary();
  EXPECT_FALSE(s.target_reached);
  EXPECT_EQ(s.max_spp, 24u);
  EXPECT_GT(s.unconverged_pixels, 0);
}

// A farm's way to the same frame: tiles rendered from sample 0 to their plans, the blocks'
// statistics gathered from the tiles after each pass, the next pass planned from them, and only the
// tiles whose blocks take more samples rendered again.
FrameResult render_as_a_farm(const RenderScene& rs, int tile_size, int* passes, int* tiles_rendered) {
  const ImageSettings& img = rs.image();
  const BlockGrid blocks(img.width, img.height);
  const TileGrid tiles(img.width, img.height, tile_size);
  std::vector<BlockStat> stats(size_t(blocks.count()));
  std::vector<uint32_t> counts;  // empty: the pilot
  std::vector<TileResult> latest(size_t(tiles.count()));
  std::vector<SamplePlan> rendered_with(size_t(tiles.count()));  // each tile's counts when last rendered
  *passes = *tiles_rendered = 0;
  while (true) {
    for (int t = 0; t < tiles.count(); ++t) {
      const TileRect rect = tiles.rect(t);
      const SamplePlan plan =
          tile_plan(blocks, rect, counts.empty() ? std::vector<uint32_t>(stats.size(), uint32_t(img.first_spp())) : counts);
      if (plan == rendered_with[size_t(t)]) continue;  // none of its blocks takes more samples
      rendered_with[size_t(t)] = plan;
      latest[size_t(t)] = render_tile_planned(rs, rect, plan);
      ++*tiles_rendered;
      for (const BlockStat& b : latest[size_t(t)].blocks) stats[size_t(b.block)] = updated_stat(stats[size_t(b.block)], b);
    }
    ++*passes;
    auto next = next_pass_counts(stats, blocks, img, *passes);
    if (!next) break;
    counts = *next;
  }
  FrameResult out;
  out.image = ImageRGB(img.width, img.height);
  out.variance.assign(out.image.pixel_count(), 0.0f);
  out.spp.assign(out.image.pixel_count(), 0);
  for (const TileResult& t : latest) {
    for (int y = 0; y < t.rect.height; ++y) {
      for (int x = 0; x < t.rect.width; ++x) {
        const size_t i = size_t(y * t.rect.width + x), o = size_t(t.rect.y0 + y) * size_t(img.width) + size_t(t.rect.x0 + x);
        for (int c = 0; c < 3; ++c) out.image.rgb[3 * o + size_t(c)] = t.rgb[3 * i + size_t(c)];
        out.variance[o] = t.variance[i];
        out.spp[o] = t.spp[i];
      }
    }
  }
  return out;
}

TEST(FrameTarget, TilesRenderedByPlanInPassesGiveTheSameFrame) {
  RenderScene rs(target_scene(75, 53, 0.004, 8, 256), 0);
  const FrameResult ref = render_frame(rs, 32, 2);
  for (int tile : {12, 32, 7}) {  // blocks straddle tiles of 7 and of 12 pixels
    int passes = 0, rendered = 0;
    const FrameResult farm = render_as_a_farm(rs, tile, &passes, &rendered);
    ASSERT_EQ(farm.image.rgb, ref.image.rgb) << "tile " << tile;
    ASSERT_EQ(farm.variance, ref.variance) << "tile " << tile;
    ASSERT_EQ(farm.spp, ref.spp) << "tile " << tile;
    EXPECT_GE(passes, 2) << "the test exercises the passes";
    const int tiles = TileGrid(75, 53, tile).count();
    if (tile < 32) {
      EXPECT_LT(rendered, passes * tiles) << "tiles whose blocks were done were rendered again";
    }
  }
}

TEST(FrameTarget, APlanOfTheWrongShapeIsRefused) {
  constexpr int B = kAllocationBlock;
  RenderScene rs(target_scene(32, 32, 0.01, 8, 64), 0);
  const size_t blocks16 = size_t(16 / B) * size_t(16 / B);  // a 16x16 tile at the origin
  EXPECT_THROW(render_tile_planned(rs, {0, 0, 16, 16}, SamplePlan(blocks16 - 1, 8)), std::invalid_argument);
  EXPECT_THROW(render_tile_planned(rs, {0, 0, 16, 16}, SamplePlan(blocks16, 4)), std::invalid_argument);    // < min_spp
  EXPECT_THROW(render_tile_planned(rs, {0, 0, 16, 16}, SamplePlan(blocks16, 128)), std::invalid_argument);  // > max_spp
  // A tile reports the blocks whose first pixel is its own, counted here pixel by pixel.
  for (const TileRect rect : {TileRect{B, B, 8, 8}, TileRect{B / 2 + 1, 1, 8, 9}}) {
    size_t origins = 0;
    for (int y = rect.y0; y < rect.y0 + rect.height; ++y) {
      for (int x = rect.x0; x < rect.x0 + rect.width; ++x) origins += x % B == 0 && y % B == 0;
    }
    const int cols = (rect.x0 + rect.width + B - 1) / B - rect.x0 / B;
    const int rows = (rect.y0 + rect.height + B - 1) / B - rect.y0 / B;
    EXPECT_EQ(render_tile_planned(rs, rect, SamplePlan(size_t(cols * rows), 16)).blocks.size(), origins);
  }
}

TEST(FrameTarget, RenderTileRefusesAFrameTarget) {
  RenderScene rs(target_scene(16, 16, 0.01, 8, 64), 0);
  EXPECT_THROW(render_tile(rs, {0, 0, 16, 16}), std::invalid_argument);
}

}  // namespace
}  // namespace tessera

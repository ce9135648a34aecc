// SPDX-License-Identifier: Apache-2.0
// Packets fill across pixels (pixel_samples.h): which samples share a packet must change no bit.
#include "render/pixel_samples.h"

#include <gtest/gtest.h>

#include <vector>

#include "render/test_scenes.h"
#include "scene/scene_parser.h"

namespace tessera {
namespace {

// Every channel of both estimates' means and their variance, bit for bit, and the sample counts.
void expect_same(const PixelEstimate& a, const PixelEstimate& b, SamplerKind kind, const char* what) {
  ASSERT_EQ(a.samples(), b.samples()) << what;
  for (int c = 0; c < 3; ++c) ASSERT_EQ(a.mean(c), b.mean(c)) << what << " channel " << c;
  ASSERT_EQ(a.variance(kind), b.variance(kind)) << what;
}

TEST(PixelSamples, APixelIsTheSameAloneOrInAnyRectangleAndInAnyNumberOfSteps) {
  // Glass, a mirror and a checker floor: camera rays that split into children packets of mixed
  // pixels, and shadow rays queued across lights.
  const Scene scene = parse_scene(test::whitted_like(23, 17, 1), "test.json");
  for (const SamplerKind kind : {SamplerKind::kSobol, SamplerKind::kCmj, SamplerKind::kIndependent}) {
    Scene s = scene;
    s.image.sampler = kind;
    s.image.spp = 11;
    RenderScene rs(s, 0);
    const TileRect rect{5, 4, 13, 9};
    // Each pixel alone, all 11 samples in one call: packets of 8 + 3 of its own samples.
    std::vector<PixelEstimate> alone(size_t(rect.pixels()));
    RayCounts rays_alone;
    for (int y = 0; y < rect.height; ++y) {
      for (int x = 0; x < rect.width; ++x) {
        render_samples(rs, {rect.x0 + x, rect.y0 + y, 1, 1}, 0, 11, &alone[size_t(y * rect.width + x)], &rays_alone);
      }
    }
    // The rectangle in three steps of 3, 1 and 7 samples: packets hold samples of up to 8 pixels.
    std::vector<PixelEstimate> steps(size_t(rect.pixels()));
    RayCounts rays_steps;
    for (const auto& [from, to] : {std::pair{0u, 3u}, {3u, 4u}, {4u, 11u}}) {
      render_samples(rs, rect, from, to, steps.data(), &rays_steps);
    }
    // Row by row (as uniform tiles render), all 11 at once.
    std::vector<PixelEstimate> rows(size_t(rect.pixels()));
    RayCounts rays_rows;
    for (int y = 0; y < rect.height; ++y) {
      render_samples(rs, {rect.x0, rect.y0 + y, rect.width, 1}, 0, 11, &rows[size_t(y * rect.width)], &rays_rows);
    }
    for (size_t i = 0; i < alone.size(); ++i) {
      expect_same(alone[i], steps[i], kind, "in steps");
      expect_same(alone[i], rows[i], kind, "in rows");
    }
    EXPECT_EQ(rays_alone.total(), rays_steps.total());
    EXPECT_EQ(rays_alone.total(), rays_rows.total());
    EXPECT_GT(rays_alone.secondary, 0u);  // the glass and the mirror are in view
    // Nothing outside the estimates it was given, and nothing for an empty range.
    std::vector<PixelEstimate> none(size_t(rect.pixels()));
    RayCounts rays_none;
    render_samples(rs, rect, 7, 7, none.data(), &rays_none);
    EXPECT_EQ(rays_none.total(), 0u);
    EXPECT_EQ(none[0].samples(), 0u);
  }
}

}  // namespace
}  // namespace tessera

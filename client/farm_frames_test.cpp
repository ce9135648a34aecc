// SPDX-License-Identifier: Apache-2.0
// What the client decides when tiles of a job arrive: which it takes, when a frame is complete,
// what it says is missing, and the frame it writes (every pixel where its tile put it).
#include "farm_frames.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>

#include "farm/tile_codec.h"
#include "tile/tile_grid.h"

namespace tessera::cli {
namespace {

namespace fs = std::filesystem;

// A 20x10 job of two frames cut into 8-pixel tiles: 3 columns x 2 rows.
tessera::v1::JobStatus job() {
  tessera::v1::JobStatus j;
  j.set_job_id("j1");
  j.set_width(20);
  j.set_height(10);
  j.set_tile_size(8);
  j.set_tiles_per_frame(6);
  j.set_first_frame(4);
  j.set_last_frame(5);
  j.set_spp(4);
  return j;
}

// Tile `index` of `frame`, each pixel's value telling where it belongs.
tessera::v1::TileData tile(int frame, int index, const std::string& job_id = "j1") {
  const TileRect r = TileGrid(20, 10, 8).rect(index);
  TileResult t;
  t.rect = r;
  for (int y = r.y0; y < r.y0 + r.height; ++y) {
    for (int x = r.x0; x < r.x0 + r.width; ++x) {
      const float v = float(frame * 10000 + y * 100 + x);
      t.rgb.insert(t.rgb.end(), {v, v, v});
      t.variance.push_back(0.01f);
      t.spp.push_back(4);
    }
  }
  t.rays.camera = uint64_t(r.pixels()) * 4;
  tessera::v1::TileData d;
  farm::encode_tile(t, &d);
  d.set_job_id(job_id);
  d.set_frame(frame);
  d.set_tile_index(index);
  d.set_worker("w" + std::to_string(index % 2));
  return d;
}

TEST(FrameAssemblerTest, AFrameIsCompleteWithItsLastTileWhateverTheOrderAndDuplicatesAreIgnored) {
  FrameAssembler a(job());
  for (int i : {5, 0, 3, 1, 4}) {
    ASSERT_EQ(a.add(tile(4, i)), "");
    EXPECT_FALSE(a.complete(4));
  }
  EXPECT_EQ(a.add(tile(4, 3)), "");  // a second copy: the first one won (not counted below)
  ASSERT_EQ(a.add(tile(4, 2)), "");
  EXPECT_TRUE(a.complete(4));
  EXPECT_FALSE(a.complete(5));
  EXPECT_EQ(a.tiles_received(), 6);
  EXPECT_EQ(a.rays_received(), uint64_t(20 * 10 * 4));
}

TEST(FrameAssemblerTest, RefusesTilesOfAnotherJobOutsideTheJobOrInTheWrongPlace) {
  FrameAssembler a(job());
  std::string err = a.add(tile(4, 0, "other"));
  EXPECT_NE(err.find("belongs to job 'other'"), std::string::npos) << err;
  err = a.add(tile(6, 0));
  EXPECT_NE(err.find("outside the job"), std::string::npos) << err;
  tessera::v1::TileData moved = tile(4, 1);
  moved.set_tile_index(2);  // tile 1's pixels claiming to be tile 2
  err = a.add(moved);
  EXPECT_NE(err.find("does not match its rectangle"), std::string::npos) << err;
  EXPECT_EQ(a.tiles_received(), 0);
}

TEST(FrameAssemblerTest, SaysWhichTilesAndFramesAreMissing) {
  FrameAssembler a(job());
  for (int i : {0, 1, 2, 4}) ASSERT_EQ(a.add(tile(4, i)), "");
  EXPECT_EQ(a.missing_tiles(4), "tiles 3, 5 missing (4 of 6 received)");
  EXPECT_EQ(a.missing_tiles(5), "tiles 0, 1, 2, 3, 4, 5 missing (0 of 6 received)");
  EXPECT_EQ(a.frames_not_written({}),
            "frame 4: tiles 3, 5 missing (4 of 6 received); frame 5: tiles 0, 1, 2, 3, 4, 5 missing (0 of 6 received)");
  // Frame 5 was written by an earlier client: only frame 4 is lost.
  EXPECT_EQ(a.frames_not_written({5}), "frame 4: tiles 3, 5 missing (4 of 6 received)");
}

TEST(FrameAssemblerTest, WritesEveryPixelWhereItsTilePutItAndThenTakesNoMoreTilesOfThatFrame) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-farm-frames-test-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  FrameAssembler a(job());
  for (int i = 5; i >= 0; --i) ASSERT_EQ(a.add(tile(5, i)), "");
  const FrameReport rep = a.write(5, (dir / "f_####.exr").string(), "scene.json", color::OutputOptions{});
  EXPECT_EQ(rep.path, (dir / "f_0005.exr").string());
  EXPECT_EQ(rep.workers, (std::set<std::string>{"w0", "w1"}));
  const ImageRGB img = read_exr(rep.path);
  ASSERT_EQ(img.width, 20);
  ASSERT_EQ(img.height, 10);
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 20; ++x) ASSERT_EQ(img.at(x, y)[1], float(50000 + y * 100 + x)) << x << "," << y;
  }
  EXPECT_TRUE(a.written(5));
  EXPECT_EQ(a.add(tile(5, 0)), "");  // ignored: the frame is written
  EXPECT_EQ(a.tiles_received(), 6);
  EXPECT_EQ(a.frames_not_written({4}), "");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
#include "result_bounds.h"

#include <gtest/gtest.h>

#include <cstring>

namespace tessera::server {
namespace {

tessera::v1::TileData tile(double seconds, uint32_t uniform_spp, uint64_t camera) {
  tessera::v1::TileData t;
  t.set_seconds(seconds);
  t.set_uniform_spp(uniform_spp);
  t.mutable_rays()->set_camera(camera);
  return t;
}

const ResultBounds kBounds{/*lease_age_seconds=*/2.0, /*pixels=*/256, /*max_spp=*/16};

TEST(ResultBounds, AnHonestTileIsWithinEveryBound) {
  EXPECT_EQ(check_result_bounds(tile(1.9, 16, 256 * 16), kBounds), "");
  EXPECT_EQ(check_result_bounds(tile(2.5, 16, 256 * 16), kBounds), "") << "within the clock slack";
}

TEST(ResultBounds, ARenderLongerThanItsLeaseIsRefused) {
  EXPECT_NE(check_result_bounds(tile(1e300, 16, 4096), kBounds).find("render time 1e+300 s is longer than its lease"),
            std::string::npos);
}

TEST(ResultBounds, SamplesOverTheJobsMostAreRefused) {
  EXPECT_NE(check_result_bounds(tile(1, 4294967295u, 4096), kBounds).find("4294967295 samples, more than the job's 16"),
            std::string::npos);
  tessera::v1::TileData t = tile(1, 0, 4096);
  std::string counts(256 * 4, '\0');
  const uint32_t big = 17;
  std::memcpy(&counts[100 * 4], &big, 4);
  t.set_spp(counts);
  EXPECT_NE(check_result_bounds(t, kBounds).find("17 samples"), std::string::npos);
}

TEST(ResultBounds, MoreCameraRaysThanSamplesAreRefused) {
  EXPECT_NE(check_result_bounds(tile(1, 16, uint64_t(1) << 40), kBounds).find("above the tile's 256 pixels x 16"),
            std::string::npos);
}

}  // namespace
}  // namespace tessera::server

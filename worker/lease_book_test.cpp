// SPDX-License-Identifier: Apache-2.0
#include "lease_book.h"

#include <gtest/gtest.h>

#include <utility>
#include <vector>

namespace tessera::worker {
namespace {

namespace v1 = tessera::v1;

std::vector<std::pair<uint64_t, int>> tiles_of(const v1::ReturnTiles& r) {
  std::vector<std::pair<uint64_t, int>> out;
  for (const v1::LeaseTile& t : r.tiles()) out.emplace_back(t.lease_id(), t.tile_index());
  return out;
}

std::vector<uint64_t> leases_of(const v1::ReturnTiles& r) { return {r.lease_ids().begin(), r.lease_ids().end()}; }

TEST(LeaseBook, ASingleTileLeaseIsForgottenWithItsResult) {
  LeaseBook book;
  book.posted(1, 5, 1);
  EXPECT_EQ(book.leases(), 1u);
  EXPECT_FALSE(book.finished(1, 5));
  EXPECT_EQ(book.leases(), 0u);
}

TEST(LeaseBook, ARevokedLeaseDropsEveryResultStillComing) {
  LeaseBook book;
  book.posted(1, 10, 3);
  EXPECT_FALSE(book.finished(1, 10));  // sent before the revoke
  book.revoke(1);
  EXPECT_TRUE(book.finished(1, 11));  // both running tiles' results are dropped, not only the first
  EXPECT_TRUE(book.finished(1, 12));
  EXPECT_EQ(book.leases(), 0u);
  book.revoke(1);  // a lease no longer held: nothing to remember
  EXPECT_EQ(book.leases(), 0u);
  EXPECT_FALSE(book.finished(1, 12));
}

TEST(LeaseBook, ARevokedTileDropsOnlyThatTile) {
  LeaseBook book;
  book.posted(1, 10, 3);
  book.revoke(1, 11);
  book.revoke(1, 40);  // not a tile of the lease: ignored
  EXPECT_FALSE(book.finished(1, 12));
  EXPECT_TRUE(book.finished(1, 11));
  EXPECT_FALSE(book.finished(1, 10));
  EXPECT_EQ(book.leases(), 0u);
}

TEST(LeaseBook, WithdrawnTilesCountAsDone) {
  LeaseBook book;
  book.posted(1, 0, 4);
  book.withdrawn(1, 3);  // a revoke took the unstarted three
  book.revoke(1);
  EXPECT_EQ(book.leases(), 1u);
  EXPECT_TRUE(book.finished(1, 0));  // the running one
  EXPECT_EQ(book.leases(), 0u);
  book.posted(2, 0, 2);
  book.withdrawn(2, 2);
  EXPECT_EQ(book.leases(), 0u);
}

TEST(LeaseBook, UntouchedLeasesGoBackWholeStartedOnesTileByTile) {
  LeaseBook book;
  book.posted(1, 0, 1);   // single tile, unstarted
  book.posted(2, 10, 3);  // span: tile 10 finished, 11 running, 12 unstarted
  book.posted(3, 20, 2);  // span, unstarted
  book.posted(4, 30, 3);  // span: tile 31 revoked and withdrawn, 30 and 32 unstarted
  EXPECT_FALSE(book.finished(2, 10));
  book.withdrawn(4, 1);
  const v1::ReturnTiles r = book.give_back({{1, 0}, {2, 12}, {3, 20}, {4, 30}, {3, 21}, {4, 32}});
  EXPECT_EQ(leases_of(r), (std::vector<uint64_t>{1, 3}));
  EXPECT_EQ(tiles_of(r), (std::vector<std::pair<uint64_t, int>>{{2, 12}, {4, 30}, {4, 32}}));
  // What was given back is settled: only lease 2's running tile is still expected.
  EXPECT_EQ(book.leases(), 1u);
  EXPECT_FALSE(book.finished(2, 11));
  EXPECT_EQ(book.leases(), 0u);
}

TEST(LeaseBook, NothingToGiveBackIsAnEmptyMessage) {
  LeaseBook book;
  const v1::ReturnTiles r = book.give_back({});
  EXPECT_EQ(r.lease_ids_size(), 0);
  EXPECT_EQ(r.tiles_size(), 0);
}

}  // namespace
}  // namespace tessera::worker

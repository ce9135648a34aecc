// SPDX-License-Identifier: Apache-2.0
// What one session holds of each lease it was given: how many of the lease's tiles are posted to
// the render pool and not finished, and which of them were revoked while rendering. A span lease
// (farm/span_lease.h) has several tiles in flight at once, so "revoked" is no longer one flag a lease's
// one result clears: a whole-lease revoke drops every result the lease still has coming, a tile
// revoke (Revoke.tiles) only that tile's, and a lease is forgotten once its last tile is done.
// Returning tiles at shutdown needs the same book: a lease none of whose tiles started goes back
// whole, one with tiles running or sent goes back tile by tile (returning it whole would make the
// coordinator discard the results still coming for it).
//
// Not thread-safe: the session guards it with its write lock.
#pragma once

#include <cstdint>
#include <set>
#include <unordered_map>
#include <vector>

#include "render_pool.h"
#include "tessera/v1/worker_service.pb.h"

namespace tessera::worker {

class LeaseBook {
 public:
  // A lease's tiles first .. first + tiles - 1 were posted to the render pool.
  void posted(uint64_t lease, int first, int tiles);
  // Unstarted tasks of the lease were withdrawn from the pool (a revoke, a failed span, the
  // worker leaving): they will never finish.
  void withdrawn(uint64_t lease, size_t tasks);
  // Revoke.lease_ids: every result the lease still has coming is to be dropped.
  void revoke(uint64_t lease);
  // Revoke.tiles: this tile's result, if it is still to come, is to be dropped.
  void revoke(uint64_t lease, int tile);
  // A tile's task ended (its result or its failure in hand): true if that is to be dropped.
  bool finished(uint64_t lease, int tile);
  // The message that gives back these withdrawn tasks (RenderPool::remove_all's keys, each
  // counted as withdrawn here): whole leases in lease_ids, tiles of leases that had started in
  // tiles. Leases are named in the order of their first key.
  tessera::v1::ReturnTiles give_back(const std::vector<TaskKey>& keys);

  // Leases with a tile still posted and not finished.
  size_t leases() const { return leases_.size(); }

 private:
  struct Lease {
    int first = 0;         // its first tile's index
    int tiles = 0;         // its tiles
    int unfinished = 0;    // posted, neither finished nor withdrawn
    bool revoked = false;  // the whole lease
    std::set<int> revoked_tiles;
  };
  // Takes `tasks` off the lease's unfinished count, forgetting it at zero.
  void settle(std::unordered_map<uint64_t, Lease>::iterator it, size_t tasks);

  std::unordered_map<uint64_t, Lease> leases_;
};

}  // namespace tessera::worker

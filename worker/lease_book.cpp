// SPDX-License-Identifier: Apache-2.0
#include "lease_book.h"

#include <algorithm>

namespace tessera::worker {

namespace v1 = tessera::v1;

void LeaseBook::posted(uint64_t lease, int first, int tiles) {
  Lease& l = leases_[lease];
  l.first = first;
  l.tiles = tiles;
  l.unfinished = tiles;
}

void LeaseBook::settle(std::unordered_map<uint64_t, Lease>::iterator it, size_t tasks) {
  it->second.unfinished -= int(std::min(tasks, size_t(it->second.unfinished)));
  if (it->second.unfinished == 0) leases_.erase(it);
}

void LeaseBook::withdrawn(uint64_t lease, size_t tasks) {
  if (tasks == 0) return;
  if (auto it = leases_.find(lease); it != leases_.end()) settle(it, tasks);
}

void LeaseBook::revoke(uint64_t lease) {
  // A lease not in the book has nothing to come (or was never ours): nothing to remember.
  if (auto it = leases_.find(lease); it != leases_.end()) it->second.revoked = true;
}

void LeaseBook::revoke(uint64_t lease, int tile) {
  auto it = leases_.find(lease);
  if (it == leases_.end()) return;
  Lease& l = it->second;
  // Kept until the lease is forgotten even if the tile is already done: a few ints a lease.
  if (tile >= l.first && tile - l.first < l.tiles) l.revoked_tiles.insert(tile);
}

bool LeaseBook::finished(uint64_t lease, int tile) {
  auto it = leases_.find(lease);
  if (it == leases_.end()) return false;
  const bool drop = it->second.revoked || it->second.revoked_tiles.erase(tile) > 0;
  settle(it, 1);
  return drop;
}

v1::ReturnTiles LeaseBook::give_back(const std::vector<TaskKey>& keys) {
  // How many tiles of each lease are given back, to tell whole leases from started ones.
  std::unordered_map<uint64_t, int> given;
  for (const TaskKey& k : keys) ++given[k.lease];
  v1::ReturnTiles out;
  std::unordered_map<uint64_t, bool> whole;  // each lease's verdict, decided at its first key
  for (const TaskKey& k : keys) {
    auto [w, first_key] = whole.try_emplace(k.lease, false);
    if (first_key) {
      auto it = leases_.find(k.lease);
      // Every tile of the lease given back: none started, so the lease goes back as one id. A
      // lease the book does not know (not posted through it) goes back whole too, as before spans.
      w->second = it == leases_.end() || given[k.lease] == it->second.tiles;
      if (w->second) out.add_lease_ids(k.lease);
    }
    if (!w->second) {
      v1::LeaseTile* t = out.add_tiles();
      t->set_lease_id(k.lease);
      t->set_tile_index(k.tile);
    }
  }
  for (const auto& [lease, n] : given) withdrawn(lease, size_t(n));
  return out;
}

}  // namespace tessera::worker

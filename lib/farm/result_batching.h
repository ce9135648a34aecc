// SPDX-License-Identifier: Apache-2.0
// How a worker gathers finished tiles into messages, and how many tiles it keeps on hand so that
// gathering never leaves a render thread waiting.
//
// The coordinator's cost is mostly per message, not per byte (about 120 us of its CPU a message on
// loopback; docs/performance.md, "The coordinator's cost per tile"): a result that waits a few
// milliseconds for the results finishing beside it saves the coordinator most of its cost. The wait
// is bounded (`linger`), a batch is sent at once when the worker has nothing else to render (the
// end of a job or a frame is never held back), and a batch never outgrows what the coordinator
// accepts in one message.
//
// While results wait, their threads go on rendering: a worker keeps enough tiles requested to
// cover the linger as well as the round trip, measured from its own tile times (`depth`).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>

namespace tessera::farm {

struct ResultBatching {
  // The longest a finished tile waits for others before it is sent. 0: every result alone.
  std::chrono::milliseconds linger{40};
  size_t max_tiles = 256;             // results in one message
  size_t max_bytes = size_t(8) << 20;  // serialized results in one message (see bytes_limit)
  // The most tiles a worker keeps beyond two per thread, however short its tiles are: a worker
  // with many tiles queued finishes a frame's last tiles late, while others idle.
  int max_extra_depth = 64;

  // Tiles to keep requested or assigned and unfinished, for `threads` render threads whose tiles
  // take `seconds_per_tile` each (wall time on one thread; <= 0: not measured yet). Two per
  // thread (one rendering, one queued behind it while the next request travels) plus what
  // finishes on every thread during one linger.
  int depth(int threads, double seconds_per_tile) const;

  // The byte bound of a batch for a coordinator that receives messages of at most
  // `coordinator_max_message` bytes (0: not said): half of it, so a batch that ends with one
  // large tile still fits.
  size_t bytes_limit(int64_t coordinator_max_message) const;
};

}  // namespace tessera::farm

// SPDX-License-Identifier: Apache-2.0
// The coordinator's side of frame targets (docs/farm.md, "Frame targets"): when a pass of a
// frame ends, the statistics its workers reported with each tile are gathered, the next pass is
// planned with the same pure functions `tessera render` calls (sampling/pass_plan.h), and the
// tiles whose blocks take more samples are sent round again with their plans. The Scheduler calls
// plan() (its PassPlanner) under the coordinator's lock.
//
// State per frame in flight: every block's record and the plan each tile was last rendered with
// (68 bytes a 2x2 block, record and count: 35 MB for a 1920x1080 frame while it is between
// passes). It lives in
// memory only: a restarted coordinator starts an unfinished frame from its pilot pass again.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "sampling/pass_plan.h"
#include "scheduler.h"

namespace tessera::server {

class FramePasses {
 public:
  // The frame-target settings a job's stored overrides resolve to (target_rmse, min_spp, max_spp,
  // sampler), and the job's size; nullopt when the job has no frame target.
  static std::optional<ImageSettings> settings_of(const JobSpec& spec);

  PassDecision plan(const JobSpec& spec, const JobId& job, int frame, int passes_done,
                    const std::vector<const TileOutput*>& outputs);
  // Drops what is held for a job's frames (the job ended).
  void forget(const JobId& job);
  size_t frames_held() const { return frames_.size(); }

 private:
  struct FrameState {
    std::vector<BlockStat> stats;                 // every block's latest record, block order
    std::vector<SamplePlan> rendered_with;        // each tile's plan when it was last rendered
  };
  std::map<std::pair<JobId, int>, FrameState> frames_;
};

}  // namespace tessera::server

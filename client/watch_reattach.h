// SPDX-License-Identifier: Apache-2.0
// When `tessera watch` (and `submit` without --detach) re-attaches to its job after losing the
// coordinator, and when it gives up. The coordinator keeps a job's finished tiles for its client,
// so a watch that loses its stream (the coordinator restarted, the network dropped) opens a new
// one and carries on from the frames it already has.
#pragma once

#include <grpcpp/support/status.h>

#include <algorithm>
#include <chrono>

namespace tessera::cli {

// What the client does when a WatchJob stream ends.
enum class StreamEnd {
  kFinished,  // the job reached a final state (done, cancelled, failed) and the stream closed cleanly
  kBadInput,  // the coordinator refused the job id (unknown, malformed): the user's input error
  kReattach,  // the coordinator went away mid-job: wait for it, then watch again
  kGiveUp,    // anything else, a loss before the job was ever seen, or too many losses in a row
};

class ReattachPolicy {
 public:
  // Re-attach attempts in a row without the job's status in between before giving up.
  static constexpr int kMaxAttempts = 30;
  // Before each attempt: a short pause, then up to min(attempt, kMaxWaitSeconds) seconds waiting
  // for the coordinator to listen (the wait ends as soon as it does).
  static constexpr std::chrono::milliseconds kPause{100};
  static constexpr int kMaxWaitSeconds = 5;

  // A stream delivered the job's status: attached again, so a coordinator restart costs one
  // attempt, not a budget spread over the whole job.
  void attached() { attempts_ = 0; }

  // The stream ended with `code`. `ended`: it had delivered the job's final state. `seen`: some
  // stream has delivered the job's status (there is a job to carry on with). kReattach counts an
  // attempt.
  StreamEnd after_stream(grpc::StatusCode code, bool ended, bool seen);

  // How long to wait for the coordinator before the attempt after_stream() just counted.
  std::chrono::seconds wait() const { return std::chrono::seconds(std::min(attempts_, kMaxWaitSeconds)); }

  int attempts() const { return attempts_; }

 private:
  int attempts_ = 0;
};

}  // namespace tessera::cli

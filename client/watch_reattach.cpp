// SPDX-License-Identifier: Apache-2.0
#include "watch_reattach.h"

namespace tessera::cli {

StreamEnd ReattachPolicy::after_stream(grpc::StatusCode code, bool ended, bool seen) {
  const bool ok = code == grpc::StatusCode::OK;
  if (ok && ended) return StreamEnd::kFinished;
  if (code == grpc::StatusCode::NOT_FOUND || code == grpc::StatusCode::INVALID_ARGUMENT) return StreamEnd::kBadInput;
  // A stream closed without error before the job reached its final state counts as lost too.
  if ((code == grpc::StatusCode::UNAVAILABLE || ok) && seen && attempts_ < kMaxAttempts) {
    ++attempts_;
    return StreamEnd::kReattach;
  }
  return StreamEnd::kGiveUp;
}

}  // namespace tessera::cli

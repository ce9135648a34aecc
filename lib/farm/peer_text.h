// SPDX-License-Identifier: Apache-2.0
// Text a peer sent (a job id, a worker's failure reason, a name), bounded before the coordinator
// echoes it in an error, writes it to its log or stores it: a peer that sends megabytes gets a
// few hundred bytes of them back, everywhere. The bounds are fixed, not flags: no legitimate
// peer comes near them.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <string>
#include <string_view>

namespace tessera::farm {

// Job ids are the coordinator's own (12 hex digits); a longer one is nobody's job.
inline constexpr size_t kMaxJobIdBytes = 64;
// A worker's reason for not rendering a tile, as stored with the job and shown to clients.
inline constexpr size_t kMaxReasonBytes = 1024;

// `s` cut to at most `max` bytes (at a UTF-8 character boundary) with "... (N bytes)" after it
// when cut, and every control character (newline included) turned into a space, so one line
// of the log stays one line.
std::string peer_text(std::string_view s, size_t max = 200);

// INVALID_ARGUMENT naming the field and the bound when `id` is longer than kMaxJobIdBytes
// (without echoing it); OK otherwise.
grpc::Status check_job_id(std::string_view id);

}  // namespace tessera::farm

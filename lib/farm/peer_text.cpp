// SPDX-License-Identifier: Apache-2.0
#include "peer_text.h"

namespace tessera::farm {

std::string peer_text(std::string_view s, size_t max) {
  size_t keep = std::min(s.size(), max);
  // Back to the start of a UTF-8 character: never half of one at the cut.
  while (keep < s.size() && keep > 0 && (static_cast<unsigned char>(s[keep]) & 0xC0) == 0x80) --keep;
  std::string out(s.substr(0, keep));
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  }
  if (keep < s.size()) out += "... (" + std::to_string(s.size()) + " bytes)";
  return out;
}

grpc::Status check_job_id(std::string_view id) {
  if (id.size() <= kMaxJobIdBytes) return grpc::Status::OK;
  return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "job_id: " + std::to_string(id.size()) +
                                                              " bytes, at most " + std::to_string(kMaxJobIdBytes) +
                                                              " (job ids are what SubmitJob returned)");
}

}  // namespace tessera::farm

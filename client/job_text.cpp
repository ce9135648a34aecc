// SPDX-License-Identifier: Apache-2.0
#include "job_text.h"

#include <cstdio>

#include "farm_frames.h"

namespace tessera::cli {

namespace v1 = tessera::v1;

bool is_final(v1::JobState s) {
  return s == v1::JOB_STATE_DONE || s == v1::JOB_STATE_CANCELLED || s == v1::JOB_STATE_FAILED;
}

const char* state_name(v1::JobState s) {
  switch (s) {
    case v1::JOB_STATE_QUEUED: return "queued";
    case v1::JOB_STATE_RUNNING: return "running";
    case v1::JOB_STATE_DONE: return "done";
    case v1::JOB_STATE_CANCELLED: return "cancelled";
    case v1::JOB_STATE_FAILED: return "failed";
    default: return "unknown";
  }
}

std::string describe_sampling(const v1::JobStatus& st) {
  const ImageSettings s = job_image_settings(st);
  if (!s.adaptive()) return std::to_string(st.spp()) + " spp";
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s %.3g (spp %d-%d)", s.frame_target() ? "target RMSE" : "block RMSE", s.target(),
                s.first_spp(), s.max_spp);
  return buf;
}

}  // namespace tessera::cli

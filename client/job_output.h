// SPDX-License-Identifier: Apache-2.0
// A job's recorded output (v1::JobOutput): the -o pattern and the frame output options `tessera
// submit` was given, stored with the job so that `tessera watch JOB` without -o writes the
// frames where and as the submitter asked, from any directory and after any restart.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "color/output_options.h"
#include "tessera/v1/client_service.pb.h"

namespace tessera::cli {

struct RecordedOutput {
  std::string pattern;  // absolute
  bool error_channels = false;
  color::OutputOptions color;
};

// The pattern made absolute against the current directory (a client attaching elsewhere must
// land in the same place).
v1::JobOutput to_job_output(const std::string& pattern, bool error_channels, const color::OutputOptions& color);
RecordedOutput from_job_output(const v1::JobOutput& o);
// `tessera status --json`'s "output": the pattern and options, or null when none is recorded.
nlohmann::json job_output_json(const v1::JobStatus& j);

}  // namespace tessera::cli

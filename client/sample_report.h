// SPDX-License-Identifier: Apache-2.0
// How a frame's error and samples are reported, the same way by `tessera render` and by the farm
// commands: the summary text, the EXR header attributes, the optional per-pixel channels
// (error.Y, spp.Y), the JSON report and the warning for a target that was not reached.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "image/exr_io.h"
#include "render/adaptive.h"
#include "scene/scene.h"

namespace tessera::cli {

// "est. RMSE 0.00213" for a uniform render, "est. RMSE 0.00198 (target 0.002), spp 16-1024
// (mean 87.4)" for a target-error render; "est. RMSE n/a" below 2 spp (no second stream).
std::string describe_samples(const SampleSummary& s, const ImageSettings& settings);

// tessera:estimatedRmse, tessera:sppMin/Max/Mean, and for target-error renders tessera:targetRmse,
// tessera:minSpp, tessera:maxSpp, tessera:unconvergedPixels.
void add_sample_attributes(const SampleSummary& s, const ImageSettings& settings, ExrAttributes* attrs);

// The per-pixel layers of --error-channels: error.Y, the estimated RMSE of each pixel's value
// (sqrt of its estimated variance), and spp.Y, the samples it took.
struct ErrorChannels {
  std::vector<float> error, spp;
  std::vector<ExrChannel> channels() const { return {{"error.Y", &error}, {"spp.Y", &spp}}; }
};
ErrorChannels make_error_channels(const std::vector<float>& variance, const std::vector<uint32_t>& spp);

// Empty when the target was met (or there is none); else one line saying how many pixels
// stopped at max_spp above the target.
std::string target_warning(const SampleSummary& s, const ImageSettings& settings);

nlohmann::json samples_json(const SampleSummary& s, const ImageSettings& settings);

}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
#include "sample_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace tessera::cli {

std::string describe_samples(const SampleSummary& s, const ImageSettings& settings) {
  char buf[256];
  if (s.max_spp < 2) return "est. RMSE n/a (fewer than 2 spp)";
  if (!settings.adaptive()) {
    std::snprintf(buf, sizeof buf, "est. RMSE %.3g", s.estimated_rmse);
  } else {
    std::snprintf(buf, sizeof buf, "est. RMSE %.3g (%s %.3g), spp %u-%u (mean %.1f)", s.estimated_rmse,
                  settings.frame_target() ? "target" : "block bound", settings.target(), s.min_spp, s.max_spp,
                  s.mean_spp);
  }
  return buf;
}

void add_sample_attributes(const SampleSummary& s, const ImageSettings& settings, ExrAttributes* attrs) {
  (*attrs)["tessera:estimatedRmse"] = s.estimated_rmse;
  (*attrs)["tessera:sppMin"] = int64_t(s.min_spp);
  (*attrs)["tessera:sppMax"] = int64_t(s.max_spp);
  (*attrs)["tessera:sppMean"] = s.mean_spp;
  if (settings.adaptive()) {
    (*attrs)[settings.frame_target() ? "tessera:targetRmse" : "tessera:blockRmse"] = settings.target();
    (*attrs)["tessera:minSpp"] = int64_t(settings.first_spp());
    (*attrs)["tessera:maxSpp"] = int64_t(settings.max_spp);
    (*attrs)["tessera:unconvergedPixels"] = s.unconverged_pixels;
  }
}

ErrorChannels make_error_channels(const std::vector<float>& variance, const std::vector<uint32_t>& spp) {
  ErrorChannels c;
  c.error.resize(variance.size());
  c.spp.resize(spp.size());
  for (size_t i = 0; i < variance.size(); ++i) c.error[i] = std::sqrt(variance[i]);
  for (size_t i = 0; i < spp.size(); ++i) c.spp[i] = float(spp[i]);
  return c;
}

std::string target_warning(const SampleSummary& s, const ImageSettings& settings) {
  if (!settings.adaptive() || s.target_reached) return {};
  char buf[320];
  if (settings.frame_target()) {
    std::snprintf(buf, sizeof buf,
                  "target RMSE %.3g not reached: frame estimated RMSE %.3g, with %.1f%% of pixels at --max-spp %d",
                  settings.target_rmse, s.estimated_rmse,
                  100.0 * double(s.unconverged_pixels) / double(std::max<int64_t>(1, s.pixels)), settings.max_spp);
    return buf;
  }
  std::snprintf(buf, sizeof buf,
                "block RMSE %.3g not reached everywhere: %lld of %lld blocks (%.1f%% of pixels) stopped at "
                "--max-spp %d above it; frame estimated RMSE %.3g",
                settings.block_rmse, (long long)s.unconverged_blocks, (long long)s.blocks,
                100.0 * double(s.unconverged_pixels) / double(std::max<int64_t>(1, s.pixels)),
                settings.max_spp, s.estimated_rmse);
  return buf;
}

nlohmann::json samples_json(const SampleSummary& s, const ImageSettings& settings) {
  nlohmann::json j{{"estimated_rmse", s.max_spp < 2 ? nlohmann::json(nullptr) : nlohmann::json(s.estimated_rmse)},
                   {"spp_min", s.min_spp},
                   {"spp_max", s.max_spp},
                   {"spp_mean", s.mean_spp}};
  if (settings.adaptive()) {
    j[settings.frame_target() ? "target_rmse" : "block_rmse"] = settings.target();
    j["min_spp"] = settings.first_spp();
    j["max_spp"] = settings.max_spp;
    j["target_reached"] = s.target_reached;
    j["unconverged_pixels"] = s.unconverged_pixels;
  }
  return j;
}

}  // namespace tessera::cli

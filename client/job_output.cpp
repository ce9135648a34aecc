// SPDX-License-Identifier: Apache-2.0
#include "job_output.h"

#include <filesystem>

namespace tessera::cli {

v1::JobOutput to_job_output(const std::string& pattern, bool error_channels, const color::OutputOptions& color) {
  v1::JobOutput o;
  o.set_pattern(std::filesystem::absolute(pattern).lexically_normal().string());
  o.set_error_channels(error_channels);
  o.set_tonemap(color.tonemap);
  o.set_exposure_ev(color.exposure_ev);
  o.set_white(color.white);
  o.set_format(color.format);
  o.set_colors(color.colors);
  o.set_dither(color.dither);
  o.set_exr_compression(color.exr_compression);
  return o;
}

RecordedOutput from_job_output(const v1::JobOutput& o) {
  RecordedOutput r;
  r.pattern = o.pattern();
  r.error_channels = o.error_channels();
  // Empty strings are options the submitting client left at their defaults.
  if (!o.tonemap().empty()) r.color.tonemap = o.tonemap();
  r.color.exposure_ev = o.exposure_ev();
  r.color.white = o.white();
  r.color.format = o.format();
  r.color.colors = o.colors();
  if (!o.dither().empty()) r.color.dither = o.dither();
  if (!o.exr_compression().empty()) r.color.exr_compression = o.exr_compression();
  return r;
}

nlohmann::json job_output_json(const v1::JobStatus& j) {
  if (!j.has_output()) return nullptr;
  const v1::JobOutput& o = j.output();
  return {{"pattern", o.pattern()},       {"error_channels", o.error_channels()}, {"tonemap", o.tonemap()},
          {"exposure_ev", o.exposure_ev()}, {"white", o.white()},                 {"format", o.format()},
          {"colors", o.colors()},           {"dither", o.dither()},               {"exr_compression", o.exr_compression()}};
}

}  // namespace tessera::cli

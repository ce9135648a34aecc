// SPDX-License-Identifier: Apache-2.0
#include "farm_frames.h"

#include <chrono>
#include <iostream>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "farm/temp_file.h"
#include "farm/tile_codec.h"
#include "image/output_path.h"
#include "sample_report.h"
#include "scene/scene_parser.h"

namespace tessera::cli {

namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

ImageSettings job_image_settings(const tessera::v1::JobStatus& job) {
  ImageSettings s;
  s.width = job.width();
  s.height = job.height();
  s.spp = job.spp();
  const auto& o = job.overrides();
  if (o.has_target_rmse()) s.target_rmse = o.target_rmse();
  if (o.has_block_rmse()) s.block_rmse = o.block_rmse();
  if (o.has_min_spp()) s.min_spp = o.min_spp();
  if (o.has_max_spp()) s.max_spp = o.max_spp();
  if (o.has_sampler()) s.sampler = sampler_from_name(o.sampler()).value_or(s.sampler);
  return s;
}

std::string preview_path(const std::string& frame_path) {
  const std::filesystem::path p(frame_path);
  return (p.parent_path() / (p.stem().string() + ".preview" + p.extension().string())).string();
}

FrameAssembler::FrameAssembler(const tessera::v1::JobStatus& job)
    : job_(job), grid_(job.width(), job.height(), job.tile_size()), settings_(job_image_settings(job)) {}

std::string FrameAssembler::add(const tessera::v1::TileData& tile) {
  if (tile.frame() < job_.first_frame() || tile.frame() > job_.last_frame() || tile.tile_index() < 0 ||
      tile.tile_index() >= job_.tiles_per_frame()) {
    return "tile " + std::to_string(tile.tile_index()) + " of frame " + std::to_string(tile.frame()) +
           " is outside the job";
  }
  // A tile of another job (a coordinator serving a damaged store) would put wrong pixels into
  // this frame: refuse it, by name.
  if (tile.job_id() != job_.job_id()) {
    return "tile " + std::to_string(tile.tile_index()) + " of frame " + std::to_string(tile.frame()) +
           " belongs to job '" + tile.job_id() + "', not " + job_.job_id();
  }
  if (written_.count(tile.frame())) return "";
  Frame& f = frames_[tile.frame()];
  if (f.pixels.has(tile.tile_index())) return "";  // a second copy: the first one won
  TileResult r;
  if (std::string why = farm::decode_tile_in_image(tile, job_.width(), job_.height(), &r); !why.empty()) return why;
  // Tiles of workers that predate per-pixel sample counts: every pixel took the job's spp.
  if (r.spp.empty()) r.spp.assign(r.variance.size(), uint32_t(job_.spp()));
  if (f.pixels.image().width == 0) {
    f.pixels = FrameAssembly(grid_);
    f.first = now_s();
  }
  if (std::string why = f.pixels.place(tile.tile_index(), r); !why.empty()) {
    return why + " of frame " + std::to_string(tile.frame());
  }
  for (float v : r.variance) variance_sum_ += double(v);
  pixels_ += int64_t(r.variance.size());
  f.last = now_s();
  f.tile_seconds += r.seconds;
  f.rays += r.rays.total();
  f.workers.insert(tile.worker());
  rays_ += r.rays.total();
  ++tiles_;
  return "";
}

bool FrameAssembler::complete(int frame) const {
  auto it = frames_.find(frame);
  return it != frames_.end() && it->second.pixels.complete();
}

std::string FrameAssembler::missing_tiles(int frame) const {
  auto it = frames_.find(frame);
  const auto have = [&](int t) { return it != frames_.end() && it->second.pixels.has(t); };
  const int received = it == frames_.end() ? 0 : it->second.pixels.tiles_done();
  std::string list;
  int listed = 0, missing = 0;
  for (int t = 0; t < job_.tiles_per_frame(); ++t) {
    if (have(t)) continue;
    ++missing;
    if (listed < 10) {
      list += (list.empty() ? "" : ", ") + std::to_string(t);
      ++listed;
    }
  }
  if (missing > listed) list += ", ...";
  return (missing == 1 ? "tile " : "tiles ") + list + " missing (" + std::to_string(received) + " of " +
         std::to_string(job_.tiles_per_frame()) + " received)";
}

std::string FrameAssembler::frames_not_written(const std::set<int>& delivered_before) const {
  std::string out;
  int lost = 0;
  for (int f = job_.first_frame(); f <= job_.last_frame(); ++f) {
    if (written_.count(f) || delivered_before.count(f)) continue;
    if (++lost <= 5) out += (out.empty() ? "" : "; ") + std::string("frame ") + std::to_string(f) + ": " + missing_tiles(f);
  }
  if (lost > 5) out += "; and " + std::to_string(lost - 5) + " more frames";
  return out;
}

FrameReport FrameAssembler::write(int frame, const std::string& pattern, const std::string& scene_name,
                                  const color::OutputOptions& color, bool error_channels) {
  Frame& f = frames_.at(frame);
  FrameReport rep;
  rep.frame = frame;
  rep.path = frame_output_path(pattern, frame);
  rep.wall_seconds = f.last - f.first;
  rep.tile_seconds = f.tile_seconds;
  rep.rays = f.rays;
  rep.workers = f.workers;
  const ImageRGB& image = f.pixels.image();
  rep.samples = summarize_samples(f.pixels.variance(), f.pixels.spp(), image.width, image.height, settings_);
  std::string workers;
  for (const auto& w : f.workers) workers += (workers.empty() ? "" : ",") + w;
  ExrAttributes attrs{{"renderer", std::string("tessera 0.1.0 (farm)")},
                      {"tessera:scene", scene_name},
                      {"tessera:job", job_.job_id()},
                      {"tessera:frame", int64_t(frame)},
                      {"tessera:renderSeconds", rep.wall_seconds},
                      {"tessera:tileSeconds", rep.tile_seconds},
                      {"tessera:raysTraced", std::to_string(rep.rays)},
                      {"tessera:workers", workers}};
  if (!settings_.adaptive()) attrs["tessera:spp"] = int64_t(job_.spp());
  add_sample_attributes(rep.samples, settings_, &attrs);
  const auto parent = std::filesystem::path(rep.path).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  farm::write_in_place(rep.path, [&](const std::string& tmp) {
    if (color::is_float_exr_output(color, rep.path)) {
      const ErrorChannels channels =
          error_channels ? make_error_channels(f.pixels.variance(), f.pixels.spp()) : ErrorChannels{};
      write_exr(tmp, image, attrs, ExrPixelType::kFloat,
                error_channels ? channels.channels() : std::vector<ExrChannel>{},
                parse_exr_compression(color.exr_compression));
    } else {
      color::write_output(image, tmp, color, std::cout, rep.path);
    }
  });
  std::filesystem::remove(preview_path(rep.path), ec);  // the preview has served its purpose
  written_.insert(frame);
  frames_.erase(frame);  // free the pixels
  return rep;
}

int FrameAssembler::write_previews(const std::string& pattern, const color::OutputOptions& color) {
  int written = 0;
  for (const auto& [frame, f] : frames_) {
    if (f.pixels.tiles_done() == 0 || f.pixels.complete()) continue;
    const std::string path = preview_path(frame_output_path(pattern, frame));
    farm::write_in_place(path, [&](const std::string& tmp) {
      if (color::is_float_exr_output(color, path)) {
        write_exr(tmp, f.pixels.image(),
                  {{"tessera:job", job_.job_id()},
                   {"tessera:frame", int64_t(frame)},
                   {"tessera:preview", std::string("missing tiles are black")},
                   {"tessera:tilesDone", int64_t(f.pixels.tiles_done())},
                   {"tessera:tilesTotal", int64_t(job_.tiles_per_frame())}},
                  ExrPixelType::kFloat, {}, parse_exr_compression(color.exr_compression));
      } else {
        std::ostringstream quiet;  // the conversion report of a preview is noise
        color::write_output(f.pixels.image(), tmp, color, quiet);
      }
    });
    ++written;
  }
  return written;
}

}  // namespace tessera::cli

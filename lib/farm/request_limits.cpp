// SPDX-License-Identifier: Apache-2.0
#include "farm/request_limits.h"

#include <CLI/CLI.hpp>

#include "tile/tile_grid.h"

namespace tessera::farm {

void Limits::add_flags(CLI::App& app) {
  app.add_option("--max-message-bytes", max_message_bytes, "Largest gRPC message accepted")
      ->check(CLI::Range(int64_t(2) << 20, int64_t(1) << 30))->capture_default_str()->group("Limits");
  app.add_option("--max-bundle-bytes", max_bundle_bytes, "Largest scene bundle accepted")
      ->check(CLI::Range(int64_t(1), int64_t(2000) << 20))->capture_default_str()->group("Limits");
  app.add_option("--max-pixels", max_pixels, "Largest width*height of a job")
      ->check(CLI::Range(int64_t(1), int64_t(16384) * 16384))->capture_default_str()->group("Limits");
  app.add_option("--max-spp", max_spp, "Most samples per pixel")
      ->check(CLI::Range(1, tessera::SceneLimits::kMaxSpp))->capture_default_str()->group("Limits");
  app.add_option("--max-frames", max_frames, "Most frames in one job")
      ->check(CLI::Range(1, tessera::SceneLimits::kMaxFrames))->capture_default_str()->group("Limits");
  app.add_option("--max-job-tiles", max_job_tiles,
                 "Most tiles of one job held in memory: of its frames started and not yet received by a client "
                 "(each tile costs ~100 bytes of coordinator memory; a frame not started, none)")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 40))->capture_default_str()->group("Limits");
  app.add_option("--max-resident-tiles", max_resident_tiles,
                 "Most tiles of all jobs held in memory together (of frames started and not yet received)")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 40))->capture_default_str()->group("Limits");
  app.add_option("--max-primitives", max_primitives, "Most primitives in a scene (triangles of every mesh instance)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 40))->capture_default_str()->group("Limits");
  app.add_option("--max-texture-pixels", max_texture_pixels,
                 "Most texture pixels in a scene (all its glTF images together; at most the default, which workers use)")
      ->check(CLI::Range(uint64_t(1), SceneLoadOptions{}.max_texture_pixels))->capture_default_str()->group("Limits");
  app.add_option("--max-jobs-per-client", max_jobs_per_client, "Most queued or running jobs per client")
      ->check(CLI::Range(1, 1000000))->capture_default_str()->group("Limits");
  app.add_option("--max-concurrent-uploads", max_concurrent_uploads,
                 "Most bundle uploads in progress at once (each streams to disk: one chunk of memory)")
      ->check(CLI::Range(1, 10000))
      ->group("Limits")
      ->capture_default_str();
  app.add_option("--upload-idle-seconds", upload_idle_seconds,
                 "An upload that sends no chunk (1 MiB) for this long is ended and its slot freed (links slower "
                 "than 1 MiB in this time need more)")
      ->check(CLI::Range(0.1, 86400.0))
      ->group("Limits")
      ->capture_default_str();
}

grpc::Status over_limit(grpc::StatusCode code, const std::string& what, int64_t value, const char* flag,
                        int64_t limit) {
  return grpc::Status(code, what + " is " + std::to_string(value) + ", over this coordinator's limit " +
                                std::to_string(limit) + " (tessera-server " + flag + ")");
}

grpc::Status Limits::check_job(const Scene& scene, int first_frame, int last_frame, int tile) const {
  const int64_t pixels = int64_t(scene.image.width) * scene.image.height;
  if (pixels > max_pixels) {
    return over_limit(grpc::StatusCode::INVALID_ARGUMENT,
                      "resolution " + std::to_string(scene.image.width) + "x" + std::to_string(scene.image.height) +
                          " (width*height)",
                      pixels, "--max-pixels", max_pixels);
  }
  if (scene.image.adaptive() && scene.image.max_spp > max_spp) {
    return over_limit(grpc::StatusCode::INVALID_ARGUMENT, "max_spp (of a target-error render)", scene.image.max_spp,
                      "--max-spp", max_spp);
  }
  if (!scene.image.adaptive() && scene.image.spp > max_spp) {
    return over_limit(grpc::StatusCode::INVALID_ARGUMENT, "spp", scene.image.spp, "--max-spp", max_spp);
  }
  const int64_t frames = int64_t(last_frame) - first_frame + 1;
  if (frames > max_frames) {
    return over_limit(grpc::StatusCode::INVALID_ARGUMENT, "the job's frame count", frames, "--max-frames", max_frames);
  }
  if (tile > 0) {
    // A frame's tiles are held in memory from its first tile to its delivery: one frame must fit.
    const int64_t per_frame = TileGrid(scene.image.width, scene.image.height, tile).count();
    if (per_frame > max_job_tiles) {
      return over_limit(grpc::StatusCode::INVALID_ARGUMENT,
                        "the tile count of one frame (" + std::to_string(scene.image.width) + "x" +
                            std::to_string(scene.image.height) + " in tiles of " + std::to_string(tile) +
                            " px; larger tiles need fewer)",
                        per_frame, "--max-job-tiles", max_job_tiles);
    }
  }
  return grpc::Status::OK;
}

}  // namespace tessera::farm

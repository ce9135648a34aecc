// SPDX-License-Identifier: Apache-2.0
// Limits on everything a peer can send the coordinator. Each refusal names the limit, its value
// and the `tessera-server` flag that changes it. Defaults protect a coordinator with a few GiB of
// memory; raise them for bigger shots.
// (Not "limits.h": that name would shadow <limits.h> on an include path that holds this folder.)
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <string>

#include "scene/scene.h"
#include "scene/scene_parser.h"

namespace CLI {
class App;
}

namespace tessera::farm {

struct Limits {
  int64_t max_message_bytes = 64 << 20;       // any one gRPC message (a 256x256 tile is 1 MiB)
  int64_t max_bundle_bytes = int64_t(1) << 30;  // an uploaded scene bundle
  int64_t max_pixels = int64_t(8192) * 8192;  // width * height of a job's frames
  int max_spp = 65536;
  int max_frames = 10000;                     // frames in one job
  // Tiles the coordinator holds in memory, of one job and of every job together: the tiles of
  // the frames started and not yet acknowledged by a client (a frame not started costs a few
  // bytes, whatever its size). Each costs the coordinator about 100 bytes besides its pixels, so
  // the defaults hold a job's tile tables to ~1 GB and all of them to ~2 GB. A job whose one frame
  // is over either is refused; one whose next frame would go over waits for clients to receive
  // frames (docs/farm.md, "Memory").
  int64_t max_job_tiles = 10000000;
  int64_t max_resident_tiles = 20000000;
  uint64_t max_primitives = 20000000;         // triangles of every mesh instance + spheres + planes
  // Pixels of all a scene's texture images together (glTF), checked while decoding. Workers load
  // with the library's limit, so this can only lower it.
  uint64_t max_texture_pixels = SceneLoadOptions{}.max_texture_pixels;
  int max_jobs_per_client = 100;              // queued or running jobs of one client identity
  int max_concurrent_uploads = 4;             // bundle uploads in progress at once (bundle_upload.h)
  // How long an upload in progress may wait for its next chunk (a 1 MiB message) before it is
  // ended and its slot given back: a stalled client must not hold a slot for good.
  double upload_idle_seconds = 30;

  // Adds --max-message-bytes, --max-bundle-bytes, ... to the server's command line.
  void add_flags(CLI::App& app);
  // INVALID_ARGUMENT naming the limit if the job's resolution, spp, frame count or tile count
  // (frames cut into tiles of `tile` px) is over it.
  grpc::Status check_job(const Scene& scene, int first_frame, int last_frame, int tile) const;
};

// "RESOURCE_EXHAUSTED: <what> is N, over the limit --flag M" and friends, in one format.
grpc::Status over_limit(grpc::StatusCode code, const std::string& what, int64_t value, const char* flag,
                        int64_t limit);

}  // namespace tessera::farm

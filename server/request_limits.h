// Limits on everything a peer can send the coordinator. Each refusal names the limit, its value
// and the `tessera-server` flag that changes it. Defaults protect a coordinator with a few GiB of
// memory; raise them for bigger shots.
// (Not "limits.h": server/ is on the include path, and that name would shadow <limits.h>.)
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <string>

#include "scene/scene.h"
#include "scene/scene_parser.h"

namespace CLI {
class App;
}

namespace tessera::server {

struct Limits {
  int64_t max_message_bytes = 64 << 20;       // any one gRPC message (a 256x256 tile is 1 MiB)
  int64_t max_bundle_bytes = int64_t(1) << 30;  // an uploaded scene bundle
  int64_t max_pixels = int64_t(8192) * 8192;  // width * height of a job's frames
  int max_spp = 65536;
  int max_frames = 10000;                     // frames in one job
  uint64_t max_primitives = 20000000;         // triangles of every mesh instance + spheres + planes
  // Pixels of all a scene's texture images together (glTF), checked while decoding. Workers load
  // with the library's limit, so this can only lower it.
  uint64_t max_texture_pixels = SceneLoadOptions{}.max_texture_pixels;
  int max_jobs_per_client = 100;              // queued or running jobs of one client identity
  int max_concurrent_uploads = 4;             // bundle uploads in progress at once (bundle_upload.h)

  // Adds --max-message-bytes, --max-bundle-bytes, ... to the server's command line.
  void add_flags(CLI::App& app);
  // INVALID_ARGUMENT naming the limit if the job's resolution, spp or frame count is over it.
  grpc::Status check_job(const Scene& scene, int first_frame, int last_frame) const;
};

// "RESOURCE_EXHAUSTED: <what> is N, over the limit --flag M" and friends, in one format.
grpc::Status over_limit(grpc::StatusCode code, const std::string& what, int64_t value, const char* flag,
                        int64_t limit);

// Active jobs per client identity (a TLS client certificate's CN, else the peer's address without
// the port). A submission reserves a slot before the scene is parsed, so concurrent submissions
// cannot overshoot; jobs that ended are forgotten the next time that client submits. Each job
// stores its owner, so the count survives a coordinator restart (restore()).
class JobQuota {
 public:
  explicit JobQuota(int max_jobs) : max_(max_jobs) {}
  // Forgets ended jobs (`active(job)` false), then reserves a slot or returns RESOURCE_EXHAUSTED.
  template <class ActiveFn>
  grpc::Status reserve(const std::string& client, ActiveFn active);
  // After the submission: records the job (empty id: it failed) and releases the reservation.
  void settle(const std::string& client, const std::string& job_id);
  // A job of `client` restored from the database at startup.
  void restore(const std::string& client, const std::string& job_id);

 private:
  int max_;
  std::mutex mu_;
  std::map<std::string, std::set<std::string>> jobs_;
  std::map<std::string, int> pending_;
};

// The identity a client's jobs are counted under and owned by (job_access.h): "cn:CN" of a TLS
// client certificate, else "token:NAME" of a named client token (`token_name`, from
// Authenticator::check), else the peer's address without the port.
std::string client_identity(const grpc::ServerContextBase& ctx, const std::string& token_name = {});

template <class ActiveFn>
grpc::Status JobQuota::reserve(const std::string& client, ActiveFn active) {
  std::lock_guard lock(mu_);
  auto& jobs = jobs_[client];
  for (auto it = jobs.begin(); it != jobs.end();) it = active(*it) ? std::next(it) : jobs.erase(it);
  const int64_t n = int64_t(jobs.size()) + pending_[client];
  if (n >= max_) {
    return over_limit(grpc::StatusCode::RESOURCE_EXHAUSTED, "active jobs of client " + client, n + 1,
                      "--max-jobs-per-client", max_);
  }
  ++pending_[client];
  return grpc::Status::OK;
}

}  // namespace tessera::server

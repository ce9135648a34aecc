// SPDX-License-Identifier: Apache-2.0
// `tessera submit SCENE -o OUT`: checks the scene here, uploads its bundle unless the coordinator
// has it, submits the job and (unless --detach) watches it to the end (watch_job.h).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "bundle_upload.h"
#include "commands.h"
#include "farm/bundle.h"
#include "farm/overrides_codec.h"
#include "farm_command.h"
#include "image_options.h"
#include "job_output.h"
#include "job_text.h"
#include "output_flags.h"
#include "scene/scene_parser.h"
#include "watch_job.h"

namespace tessera::cli {

namespace v1 = tessera::v1;
namespace fs = std::filesystem;

namespace {

struct SubmitArgs {
  std::string scene, output, coordinator, frames, name;
  SecurityFlags security;
  ImageOptions image;
  int tile = 32;
  int priority = 0;
  bool detach = false;
  bool quiet = false;
  bool error_channels = false;
  double preview_every = 0;
  color::OutputOptions color;
};

struct FrameRange {
  int first, last;
};

// --frames A-B or A, checked against the scene's frames; empty: all of them.
FrameRange parse_frames(const std::string& frames, int frame_count) {
  int first = 0, last = frame_count - 1;
  if (!frames.empty()) {
    const auto dash = frames.find('-');
    try {
      first = std::stoi(frames.substr(0, dash));
      last = dash == std::string::npos ? first : std::stoi(frames.substr(dash + 1));
    } catch (const std::exception&) {
      throw CommandError{kExitBadInput, "--frames: expected A or A-B, got '" + frames + "'"};
    }
    if (first < 0 || last >= frame_count || first > last) {
      throw CommandError{kExitBadInput, "--frames " + frames + ": the scene has frames 0-" +
                                            std::to_string(frame_count - 1)};
    }
  }
  return {first, last};
}

void upload_if_missing(FarmClient& client, const farm::BuiltBundle& b) {
  if (!upload_bundle_if_missing(client, b)) return;
  std::printf("uploaded scene bundle %s (%zu files, %zu bytes)\n", b.sha256.substr(0, 12).c_str(), b.files,
              b.bytes.size());
}

v1::SubmitJobRequest job_request(const SubmitArgs& a, const std::string& bundle_sha256, const ImageOverrides& o,
                                 FrameRange frames) {
  v1::SubmitJobRequest req;
  req.set_bundle_sha256(bundle_sha256);
  farm::to_proto(o, req.mutable_overrides());
  // The coordinator and workers read the bundle's glTF exactly so (checked by load_scene_with).
  farm::to_proto(a.image.gltf_options(), req.mutable_overrides());
  req.set_first_frame(frames.first);
  req.set_last_frame(frames.last);
  req.set_tile_size(a.tile);
  req.set_priority(a.priority);
  req.set_name(a.name.empty() ? fs::path(a.scene).filename().string() : a.name);
  // Recorded with the job: `tessera watch JOB` without -o writes the frames there, as asked here.
  if (!a.output.empty()) *req.mutable_output() = to_job_output(a.output, a.error_channels, a.color);
  return req;
}

int run_submit(const SubmitArgs& a) {
  // Validate locally first: the same message as `tessera render` for a bad scene.
  Scene scene;
  ImageOverrides o;
  try {
    scene = load_scene_with(a.scene, a.image, &o);
  } catch (const SceneError& e) {
    throw CommandError{kExitBadInput, e.what()};
  }
  const FrameRange frames = parse_frames(a.frames, scene.frame_count());
  if (!a.detach) check_output_writable(a.output, frames.first);

  FarmClient client = connect(a.coordinator, a.security);
  farm::BuiltBundle bundle;
  try {
    bundle = farm::make_bundle(a.scene, scene.dependencies);
  } catch (const farm::BundleError& e) {
    throw CommandError{kExitBadInput, e.what()};
  }
  upload_if_missing(client, bundle);

  const v1::SubmitJobRequest req = job_request(a, bundle.sha256, o, frames);
  v1::JobStatus st;
  auto ctx = client.context();
  grpc::Status s = client.stub().SubmitJob(ctx.get(), req, &st);
  if (!s.ok()) {
    throw CommandError{s.error_code() == grpc::StatusCode::INVALID_ARGUMENT ? kExitBadInput : kExitFailure,
                       client.describe(s, "submitting the job")};
  }
  std::printf("job %s submitted to %s: frames %d-%d, %dx%d, %s, %lld tiles\n", st.job_id().c_str(),
              client.address().c_str(), st.first_frame(), st.last_frame(), st.width(), st.height(),
              describe_sampling(st).c_str(), (long long)st.tiles_total());
  std::fflush(stdout);
  if (a.detach) {
    if (a.output.empty()) {
      std::printf("detached; get the frames with: tessera watch %s -o OUT_####.exr\n", st.job_id().c_str());
    } else {
      std::printf("detached; get the frames (to %s, recorded with the job) with: tessera watch %s\n",
                  req.output().pattern().c_str(), st.job_id().c_str());
    }
    return 0;
  }
  return watch_job(client, st.job_id(), {a.output, req.name(), a.quiet, a.color, a.error_channels, a.preview_every});
}

}  // namespace

void register_submit_command(CLI::App& app) {
  auto a = std::make_shared<SubmitArgs>();
  CLI::App* cmd = app.add_subcommand("submit", "Render a scene on the farm and write its frames");
  cmd->add_option("scene", a->scene, "Scene file: JSON, or glTF 2.0 (.gltf/.glb); see docs/scene-format.md")->required();
  cmd->add_option("-o,--output", a->output,
                  "Output EXR path; '#' runs become the frame number. Recorded with the job (with the output "
                  "options below): `tessera watch JOB` writes there too");
  add_coordinator_option(cmd, &a->coordinator, &a->security);
  cmd->add_option("--frames", a->frames, "Frames A-B (inclusive) or A (default: all)");
  add_image_options(*cmd, a->image);
  cmd->add_option("--tile", a->tile, "Tile size in pixels (does not change the image)")->check(CLI::Range(4, 256));
  cmd->add_option("--priority", a->priority, "Higher runs first (default 0)");
  cmd->add_option("--name", a->name, "Job name (default: the scene file name)");
  cmd->add_flag("--detach", a->detach, "Submit and return; fetch the frames later with `tessera watch`");
  cmd->add_flag("-q,--quiet", a->quiet, "No progress display");
  add_frame_output_options(cmd, &a->error_channels, &a->preview_every);
  add_output_options(*cmd, a->color);  // -o frame_####.png etc.: see `tessera convert`
  cmd->callback([a] {
    guarded("submit", [&] {
      if (a->output.empty() && !a->detach) throw CommandError{kExitBadInput, "-o/--output is required (or --detach)"};
      return run_submit(*a);
    });
  });
}

}  // namespace tessera::cli

// SPDX-License-Identifier: Apache-2.0
// Fuzz target: the scene parser, on scene JSON as a bundle would carry it. The only accepted
// failure is SceneError (a message for the user); any other exception, crash, leak or undefined
// behaviour is a bug. Mesh files are confined to a directory that does not exist, so no input
// can make the parser read files of this machine (that confinement is itself under test).
#include <spdlog/spdlog.h>

#include <cstdint>
#include <cstdlib>
#include <string>

#include "scene/animation.h"
#include "scene/scene_parser.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    spdlog::set_level(spdlog::level::off);
    return true;
  }();
  (void)quiet;
  tessera::SceneLoadOptions options;
  options.confine_to = "/nonexistent-tessera-fuzz";
  options.max_primitives = 1000000;
  try {
    tessera::Scene scene = tessera::parse_scene(std::string(reinterpret_cast<const char*>(data), size),
                                                "/nonexistent-tessera-fuzz/scene.json", options);
    // Invariants of an accepted scene: the limits held, and every frame evaluates.
    if (scene.image.width < 1 || scene.image.height < 1 || scene.image.spp < 1) std::abort();
    if (scene.frame_count() < 1 || scene.frame_count() > tessera::SceneLimits::kMaxFrames) std::abort();
    if (tessera::primitive_count(scene) > options.max_primitives) std::abort();
    tessera::evaluate_frame(scene, 0);
    tessera::evaluate_frame(scene, scene.frame_count() - 1);
    tessera::ImageOverrides o;
    o.width = 7;
    o.spp = 3;
    tessera::apply_overrides(scene, o);
  } catch (const tessera::SceneError&) {
  }
  return 0;
}

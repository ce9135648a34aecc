// SPDX-License-Identifier: Apache-2.0
// Allowed ranges of a scene's settings, shared by the parser, the glTF reader, the CLI and the
// coordinator's limits.
#pragma once

namespace tessera {

struct SceneLimits {
  static constexpr int kMaxResolution = 16384;
  static constexpr int kMaxSpp = 65536;
  static constexpr int kMaxDepth = 64;
  static constexpr int kMaxFrames = 100000;
};

}  // namespace tessera

// SPDX-License-Identifier: Apache-2.0
// Output file naming shared by `tessera render` and the farm client.
#pragma once

#include <string>

namespace tessera {

// "out/frame_####.exr" -> "out/frame_0007.exr" for frame 7: the first run of '#' becomes the
// frame number zero-padded to the run's length (longer numbers are not truncated). A pattern
// without '#' is returned unchanged.
inline std::string frame_output_path(const std::string& pattern, int frame) {
  const auto first = pattern.find('#');
  if (first == std::string::npos) return pattern;
  auto last = first;
  while (last < pattern.size() && pattern[last] == '#') ++last;
  std::string num = std::to_string(frame);
  if (num.size() < last - first) num.insert(0, last - first - num.size(), '0');
  return pattern.substr(0, first) + num + pattern.substr(last);
}

}  // namespace tessera

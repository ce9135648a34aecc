// SPDX-License-Identifier: Apache-2.0
// Durations as the client prints them: "M:SS" under an hour, "H:MM:SS" from an hour on.
#pragma once

#include <string>

namespace tessera::cli {

// Rounded to the nearest second; "?" for a negative or non-finite duration (an unknown ETA).
std::string format_duration(double seconds);

}  // namespace tessera::cli

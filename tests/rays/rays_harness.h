// SPDX-License-Identifier: Apache-2.0
// The ray service's end-to-end tests' helpers: tessera-rays as a process beside a test Farm
// (tests/farm/farm_harness.h), a file of rays at the bunny, polling.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "../farm/farm_harness.h"

namespace tessera::farmtest {

// Starts tessera-rays for `farm`'s coordinator and returns its address once it listens ("" and a
// test failure if it did not). `name` names its log and bundle cache in the farm's directory.
std::string start_rays(Farm& farm, std::unique_ptr<Process>* proc, const std::vector<std::string>& extra = {},
                       const std::string& name = "rays");

// `n` rays at the bunny of scenes/bunny.json as CSV with ids: from the camera through a jittered
// grid (coherent), then from random points in random directions (incoherent), alternately.
void write_bunny_rays(const fs::path& path, int n);

// Polls `done` every 20 ms until it is true (true) or `timeout` passed (false).
bool eventually(const std::function<bool()>& done, std::chrono::milliseconds timeout = std::chrono::seconds(20));

}  // namespace tessera::farmtest

// SPDX-License-Identifier: Apache-2.0
// Where the ray service gets its scenes: a tracer for (bundle hash, frame). The server's is
// bundle_scenes.h (bundles from the coordinator, cached like a worker's); tests give their own.
#pragma once

#include <grpcpp/grpcpp.h>

#include <functional>
#include <memory>
#include <string>

#include "rays/ray_tracer.h"

namespace tessera::rayserver {

// OK and *tracer set, or a status for the client: INVALID_ARGUMENT naming the field
// (scene.bundle_sha256 unknown or malformed, scene.frame out of range), UNAVAILABLE when the
// coordinator cannot be asked, FAILED_PRECONDITION when the bundle's scene does not load.
using SceneSource = std::function<grpc::Status(const std::string& sha256, int frame,
                                               std::shared_ptr<const rays::RayTracer>* tracer)>;

}  // namespace tessera::rayserver

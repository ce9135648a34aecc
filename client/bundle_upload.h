// SPDX-License-Identifier: Apache-2.0
// Uploading a scene bundle to the coordinator unless it has it already (HasBundle, then
// UploadBundle in 1 MiB chunks). Used by `tessera submit` and `tessera rays --server`.
#pragma once

#include "farm/bundle.h"
#include "farm_client.h"

namespace tessera::cli {

// Returns true if it uploaded, false if the coordinator had the bundle. Throws CommandError
// (exit 1) with FarmClient::describe()'s message on failure.
bool upload_bundle_if_missing(FarmClient& client, const farm::BuiltBundle& bundle);

}  // namespace tessera::cli
